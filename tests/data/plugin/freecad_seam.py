# Run headless by tests/test_plugin_freecad.cpp: freecadcmd freecad_seam.py, with
#   ACCURA_SOURCE_DIR   the source tree (plugin/freecad, plugin/python, robots/)
#   ACCURA_PLUGIN_LIB   libaccura_plugin.so
#   ACCURA_MODEL        the calibrated model (tests/data/plugin/kr16_calibrated.xml)
#   ACCURA_OUT          output directory
#   ACCURA_TOL_MM       path tolerance (mm)
# Builds a FreeCAD document with a KUKA KR 16 (Robot::RobotObject; kinematic table written from
# accura's robots/kuka_kr16.xml) carrying a welding torch, and a trajectory (a seam: LIN, CIRC,
# LIN, then a long LIN with a reorientation); compensates and densifies it with
# plugin/freecad/accura_freecad.py; exports the original and the compensated trajectory as KRL
# (and the original with FreeCAD's own KukaExporter); saves the document and a summary.
import json
import os
import sys

import FreeCAD as App
import Robot

src = os.environ["ACCURA_SOURCE_DIR"]
out = os.environ["ACCURA_OUT"]
sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.join(src, "plugin", "freecad"))
import accura_freecad as af  # noqa: E402

TORCH = (20, 0, 250, 0, -30, 0)  # T_flange_tcp: the tool the model was calibrated with (mm, deg)
tol_mm = float(os.environ.get("ACCURA_TOL_MM", "0.05"))

doc = App.newDocument("AccuraSeam")
robot = doc.addObject("Robot::RobotObject", "KR16")
robot.RobotKinematicFile = af.kinematic_csv(os.path.join(src, "robots", "kuka_kr16.xml"), os.path.join(out, "kr16.csv"))
robot.Tool = af.xyzabc_to_placement(TORCH)
robot.Axis2 = -90
robot.Axis3 = 90

waypoints = [
    ("P1", "PTP", (1100, -250, 500, 0, 180, 0)),
    ("P2", "LIN", (1100, -50, 500, 0, 180, 0)),
    ("P3", "CIRC", (1180, 30, 500, 0, 180, 0)),   # auxiliary point
    ("P4", "CIRC", (1260, -50, 500, 0, 180, 0)),  # end point of the half circle
    ("P5", "LIN", (1260, -250, 500, 0, 180, 0)),
    ("P6", "LIN", (1000, 1000, 700, 40, 120, -20)),  # 1.3 m across the workspace, 45-60 deg reorientation
]
traj = doc.addObject("Robot::TrajectoryObject", "Seam")
traj.Trajectory = Robot.Trajectory(
    [Robot.Waypoint(af.xyzabc_to_placement(p), name=n, type=t, vel=200.0, cont=False, tool=1, base=0) for n, t, p in waypoints])

new, summary = af.compensate_trajectory(doc, robot, traj, os.environ["ACCURA_MODEL"], tol_mm=tol_mm,
                                        plugin_lib=os.environ["ACCURA_PLUGIN_LIB"])
with af.load_model(robot, os.environ["ACCURA_MODEL"], plugin_lib=os.environ["ACCURA_PLUGIN_LIB"]) as model:
    # every PTP with the S/T of the arm's joints there (the test checks them against these joints)
    af.export_krl(traj, os.path.join(out, "seam.src"), tool=TORCH, robot=robot, model=model)
    af.export_krl(new, os.path.join(out, "seam_accura.src"), tool=TORCH, robot=robot, model=model)
summary["arm_joints"] = {"seam": af.arm_joints(robot, traj.Trajectory.Waypoints),
                         "seam_accura": af.arm_joints(robot, new.Trajectory.Waypoints)}
af.export_krl(traj, os.path.join(out, "seam_no_st.src"), tool=TORCH)  # without the robot: PTPs without S/T

# a payload given to compensate_trajectory is the loaded model's (joint compliance): 8 kg both ways
heavy, _ = af.compensate_trajectory(doc, robot, traj, os.environ["ACCURA_MODEL"], tol_mm=tol_mm, check=False, name="Seam_8kg",
                                    plugin_lib=os.environ["ACCURA_PLUGIN_LIB"], payload_kg=8.0)
with af.load_model(robot, os.environ["ACCURA_MODEL"], plugin_lib=os.environ["ACCURA_PLUGIN_LIB"], payload_kg=8.0) as m8:
    heavy_ref, _ = af.compensate_trajectory(doc, robot, traj, None, tol_mm=tol_mm, check=False, name="Seam_8kg_ref", model=m8)
summary["payload_8kg"] = [list(af.placement_to_xyzabc(w.Pos)) for w in heavy.Trajectory.Waypoints]
summary["payload_8kg_ref"] = [list(af.placement_to_xyzabc(w.Pos)) for w in heavy_ref.Trajectory.Waypoints]
summary["payload_0kg"] = [list(af.placement_to_xyzabc(w.Pos)) for w in new.Trajectory.Waypoints]
doc.removeObject(heavy.Name)
doc.removeObject(heavy_ref.Name)

# PTPs in another configuration (A1, A2, A4 and A5 negative: S 6, T 27 by KUKA's rule): the arm
# set up there, targets made from joint values on that branch; compensated and exported
FLIP = [(-30, -80, 100, -40, -60, 50), (-20, -70, 90, -50, -45, 60), (-40, -85, 110, -30, -70, 40)]
robot.Axis1, robot.Axis2, robot.Axis3, robot.Axis4, robot.Axis5, robot.Axis6 = (-25, -75, 95, -45, -50, 55)
with af.load_model(robot, os.environ["ACCURA_MODEL"], plugin_lib=os.environ["ACCURA_PLUGIN_LIB"]) as model:
    flip = doc.addObject("Robot::TrajectoryObject", "Flip")
    flip.Trajectory = Robot.Trajectory([Robot.Waypoint(af.xyzabc_to_placement(model.forward_kinematics(q)), name="F%d" % (k + 1),
                                                       type="PTP", vel=100.0, cont=False, tool=1, base=0)
                                        for k, q in enumerate(FLIP)])
    flip_new, _ = af.compensate_trajectory(doc, robot, flip, os.environ["ACCURA_MODEL"], tol_mm=tol_mm, model=model)
    af.export_krl(flip, os.path.join(out, "flip.src"), tool=TORCH, robot=robot, model=model)
    af.export_krl(flip_new, os.path.join(out, "flip_accura.src"), tool=TORCH, robot=robot, model=model)
    # a PTP the arm cannot reach: no joints, so no S/T: the export refuses it and writes nothing
    far = doc.addObject("Robot::TrajectoryObject", "Far")
    far.Trajectory = Robot.Trajectory([Robot.Waypoint(af.xyzabc_to_placement((5000, 0, 500, 0, 180, 0)), name="FAR",
                                                      type="PTP", vel=100.0, cont=False, tool=1, base=0)])
    try:
        af.export_krl(far, os.path.join(out, "far.src"), tool=TORCH, robot=robot, model=model)
        summary["far"] = ""
    except af.AccuraFreeCADError as e:
        summary["far"] = str(e)
    doc.removeObject(far.Name)
summary["flip_joints"] = FLIP
summary["arm_joints"]["flip"] = af.arm_joints(robot, flip.Trajectory.Waypoints)
summary["arm_joints"]["flip_accura"] = af.arm_joints(robot, flip_new.Trajectory.Waypoints)

from KukaExporter import ExportCompactSub  # noqa: E402  FreeCAD's own exporter (LIN only, 3 decimals)
lin_only = doc.addObject("Robot::TrajectoryObject", "SeamLin")
lin_only.Trajectory = Robot.Trajectory([w for w in traj.Trajectory.Waypoints if w.Type != "CIRC"])
ExportCompactSub(robot, lin_only, os.path.join(out, "seam_freecad.src"))

# a robot that is not the model's (FreeCAD's KR 125) is refused before anything is compensated
other = doc.addObject("Robot::RobotObject", "KR125")
other.RobotKinematicFile = App.getResourceDir() + "Mod/Robot/Lib/Kuka/kr_125.csv"
other.Tool = af.xyzabc_to_placement(TORCH)
try:
    af.compensate_trajectory(doc, other, traj, os.environ["ACCURA_MODEL"], tol_mm=tol_mm,
                             plugin_lib=os.environ["ACCURA_PLUGIN_LIB"], name="ShouldNotExist")
    summary["wrong_robot"] = ""
except af.AccuraFreeCADError as e:
    summary["wrong_robot"] = str(e)
doc.removeObject(other.Name)

doc.saveAs(os.path.join(out, "AccuraSeam.FCStd"))
summary["objects"] = [o.Name for o in doc.Objects]
summary["waypoints"] = [[w.Name, w.Type] + list(af.placement_to_xyzabc(w.Pos)) for w in new.Trajectory.Waypoints]
with open(os.path.join(out, "summary.json"), "w") as f:
    json.dump(summary, f, indent=1)
print("accura_freecad: %d waypoints -> %d; predicted path error %.4f mm as programmed, %.4f mm with the points; "
      "FreeCAD vs accura kinematics %.3g mm" % (summary["waypoints_in"], summary["waypoints_out"],
                                                summary["max_error_uncompensated_mm"], summary["max_error_after_mm"],
                                                summary["kinematics_mm"]))
print("accura_freecad: ok")
