"""accura for FreeCAD's Robot workbench: compensate and densify a trajectory with a calibrated
model through the accura plug-in (libaccura_plugin.so, via plugin/python/accura_plugin.py), add
the result to the document as a new trajectory, and export it as KUKA KRL.

Runs in FreeCAD (GUI or headless `freecadcmd`); the macro AccuraCompensate.FCMacro calls it on
the selection. Steps (README "The plug-in"):

    import accura_freecad as af
    new, summary = af.compensate_trajectory(doc, robot, trajectory, "kr16_calibrated.xml", tol_mm=0.05)
    with af.load_model(robot, "kr16_calibrated.xml") as model:   # the PTPs get the arm's S/T
        af.export_krl(new, "/path/seam_accura.src", tool=af.placement_to_xyzabc(robot.Tool), robot=robot, model=model)

Conventions (the mapping between FreeCAD and accura):
- Kinematics. FreeCAD's Robot6Axis reads a kinematic table (CSV: a, alpha, d, theta, rotDir,
  maxAngle, minAngle, AxisVelocity; one row per axis) and builds a KDL chain of
  Segment(RotZ, Frame::DH(a, alpha, d, theta)): link i = Rz(rotDir_i * q_i) Rz(theta_i) Tz(d_i)
  Tx(a_i) Rx(alpha_i), which is accura's DH link (robot.h) with theta0 = theta and
  direction = rotDir; limits are [minAngle, maxAngle] deg. kinematic_csv() writes that table
  from an accura robot file (accura's KR 16 comes from FreeCAD's kr_16.csv; accura's Hayati
  links equal their DH form at nominal, so the table is exact), and
  check_kinematics() compares FreeCAD's forward kinematics with the model's at several axis
  positions before anything is compensated. FreeCAD applies the limits to rotDir * q, so for an
  axis with rotDir -1 the table holds accura's limits mirrored (maxAngle = -lower, minAngle =
  -upper): FreeCAD's own IK then keeps q within accura's limits.
- Frames. The robot object's Tcp is the flange in the robot base frame; its `Tool` placement is
  the tool (T_flange_tcp, accura's $TOOL). Waypoint poses are the TCP (flange * Tool) in the
  robot base frame ($BASE = $WORLD = robot base: the controller's defaults). The robot
  object's Placement (where it stands in the document) is not used. Angles: FreeCAD's
  Rotation.toEuler() is (yaw, pitch, roll) = Rz Ry Rx = KUKA (A, B, C).
- Motions. Waypoint types PTP and LIN as FreeCAD has them; a circle is two consecutive CIRC
  waypoints: the auxiliary point, then the end point. A LIN/CIRC run is compensated as one path
  from the waypoint before it; PTP waypoints are compensated as points. A PTP is compensated
  in the arm's configuration there (arm_joints: the joint values FreeCAD's IK gives from the
  robot's current axes), and export_krl writes it as the PTP's KUKA S/T.
"""
import math
import os
import sys
import tempfile

import FreeCAD as App
import Robot

_here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(_here), "python"))
import accura_plugin  # noqa: E402


class AccuraFreeCADError(Exception):
    pass


def placement_to_xyzabc(p):
    """(x, y, z, A, B, C) mm / deg of a FreeCAD Placement (A, B, C = yaw, pitch, roll)."""
    a, b, c = p.Rotation.toEuler()
    return (p.Base.x, p.Base.y, p.Base.z, a, b, c)


def xyzabc_to_placement(x):
    return App.Placement(App.Vector(x[0], x[1], x[2]), App.Rotation(x[3], x[4], x[5]))


def _compose(a, b):
    """Placement a * b."""
    return a.multiply(b)


def kinematic_csv(robot_xml, csv_path, axis_velocity_deg_s=100.0, plugin_lib=None):
    """Writes FreeCAD's kinematic table of an accura robot file (6 revolute joints, DH form at
    nominal), read by the plug-in. The table's last column (AxisVelocity) is not in accura's files:
    FreeCAD uses it only for its own simulation timing."""
    with accura_plugin.Plugin(plugin_lib).load(robot_xml) as model:
        joints = model.joints()
        if len(joints) != 6 or any(j.prismatic for j in joints):
            raise AccuraFreeCADError("%s: FreeCAD's Robot6Axis needs 6 revolute joints, found %d joints" % (robot_xml, len(joints)))
        rows = ["a    ,alpha ,d    ,theta,rotDir,maxAngle ,minAngle ,AxisVelocity"]
        for j in joints:
            lower, upper = j.lower, j.upper
            if j.direction < 0:  # FreeCAD's limits are on rotDir * q
                lower, upper = -upper, -lower
            rows.append("%r,%r,%r,%r,%d,%r,%r,%r" % (j.a_mm, j.alpha_deg, j.d_mm, j.theta0_deg, j.direction, upper, lower,
                                                      axis_velocity_deg_s))
        model.write_file(csv_path, "\n".join(rows) + "\n")
    return csv_path


class _Probe:
    """A hidden copy of `robot` (its own copy of the kinematic table: the file is included in the
    document, and removing the probe removes its included file), removed on exit."""

    def __init__(self, doc, robot):
        self.doc, self.robot = doc, robot

    def __enter__(self):
        fd, self.table = tempfile.mkstemp(prefix="accura_kinematics_", suffix=".csv")
        with os.fdopen(fd, "wb") as f, open(self.robot.RobotKinematicFile, "rb") as g:
            f.write(g.read())
        self.probe = self.doc.addObject("Robot::RobotObject", "AccuraKinematicProbe")
        self.probe.RobotKinematicFile = self.table
        return self

    def __exit__(self, *exc):
        self.doc.removeObject(self.probe.Name)
        if os.path.exists(self.table):
            os.unlink(self.table)

    def set_axes(self, q):
        """Moves the probe to joint values q (deg); returns them as FreeCAD holds them and its TCP (flange * Tool)."""
        for k in range(6):
            setattr(self.probe, "Axis%d" % (k + 1), q[k])
        return [getattr(self.probe, "Axis%d" % (k + 1)) for k in range(6)], _compose(self.probe.Tcp, self.robot.Tool)

    def solve(self, pose):
        """FreeCAD's IK (seeded with the probe's axes): the joint values that put the TCP on pose, or None."""
        target = xyzabc_to_placement(pose)
        self.probe.Tcp = target.multiply(self.robot.Tool.inverse())
        q, tcp = self.set_axes([getattr(self.probe, "Axis%d" % (k + 1)) for k in range(6)])
        d = tcp.Rotation.multiply(target.Rotation.inverted())
        return q if (tcp.Base - target.Base).Length <= 1e-3 and abs(math.degrees(d.Angle)) <= 1e-3 else None


def check_kinematics(doc, robot, model, tol_mm=1e-6, tol_deg=1e-6):
    """Largest position (mm) and angle (deg) difference between FreeCAD's forward kinematics of
    `robot` (Tcp * Tool) and the model's controller at a few axis positions. Raises when they
    differ by more than the tolerances: the document's robot is not the model's robot."""
    worst_mm = worst_deg = 0.0
    with _Probe(doc, robot) as p:
        for q in ((0, -90, 90, 0, 0, 0), (20, -70, 100, 30, 40, -60), (-45, -110, 60, -90, -30, 120),
                  (100, -30, 130, 170, 80, -170)):
            qs, fc = p.set_axes(q)
            ac = xyzabc_to_placement(model.forward_kinematics(qs, accura_plugin.CONTROLLER))
            worst_mm = max(worst_mm, (fc.Base - ac.Base).Length)
            d = fc.Rotation.multiply(ac.Rotation.inverted())
            worst_deg = max(worst_deg, abs(math.degrees(d.Angle)))
    if worst_mm > tol_mm or worst_deg > tol_deg:
        raise AccuraFreeCADError("the robot '%s' (%s) is not the model's robot: forward kinematics differ by %.6g mm and %.6g deg"
                                 % (robot.Label, robot.RobotKinematicFile, worst_mm, worst_deg))
    return worst_mm, worst_deg


def arm_joints(robot, waypoints):
    """The joint values (deg) the FreeCAD arm `robot` takes at each PTP waypoint (None for the
    others): FreeCAD's IK seeded with the previous PTP's joints (the first with the robot's current
    axes; when that finds none, again from the current axes), so that the arm keeps the
    configuration the robot is set up in. A PTP to a Cartesian target must carry it (KUKA S/T).
    Raises when FreeCAD's IK finds no joints for a PTP waypoint."""
    out = [None] * len(waypoints)
    with _Probe(robot.Document, robot) as p:
        current = [getattr(robot, "Axis%d" % (k + 1)) for k in range(6)]
        seed = current
        for i, w in enumerate(waypoints):
            if w.Type != "PTP":
                continue
            for start in (seed, current):
                p.set_axes(start)
                out[i] = p.solve(placement_to_xyzabc(w.Pos))
                if out[i] is not None:
                    break
            if out[i] is None:
                raise AccuraFreeCADError("waypoint %d (%s): FreeCAD's robot '%s' finds no joint values that put its tool there"
                                         % (i, w.Name, robot.Label))
            seed = out[i]
    return out


def load_model(robot, model_path, plugin_lib=None, payload_kg=0.0, robroot_in_world=None):
    """The plug-in's model for `robot`: the calibrated model file, with the robot's Tool as $TOOL.
    robroot_in_world (x, y, z mm, A, B, C deg): where the robot stands in the model's world, for a
    model measured in another frame (a tracker's); None: the model's own base."""
    plugin = accura_plugin.Plugin(plugin_lib)
    return plugin.load(model_path, program_tool=placement_to_xyzabc(robot.Tool), payload_kg=payload_kg,
                       robroot_in_world=robroot_in_world)


def _runs(waypoints):
    """Splits the waypoints into (start index, [motions]) runs (see the module comment)."""
    runs, i, n = [], 0, len(waypoints)
    while i < n:
        motions, j = [], i + 1
        while j < n and waypoints[j].Type in ("LIN", "CIRC"):
            w = waypoints[j]
            if w.Type == "LIN":
                motions.append(("LIN", j))
                j += 1
            else:
                if j + 1 >= n or waypoints[j + 1].Type != "CIRC":
                    raise AccuraFreeCADError("waypoint %d (%s): a CIRC waypoint (the auxiliary point) must be followed by a "
                                             "second CIRC waypoint (the end point)" % (j, w.Name))
                motions.append(("CIRC", j, j + 1))
                j += 2
        runs.append((i, motions))
        i = j
    return runs


def _waypoint(pose, like, name, type_=None):
    return Robot.Waypoint(xyzabc_to_placement(pose), name=name, type=type_ or like.Type, vel=like.Velocity,
                          cont=like.Cont, tool=like.Tool, base=like.Base)


def compensate_trajectory(doc, robot, trajectory, model_path, tol_mm=0.05, plugin_lib=None, name=None, model=None,
                          check=True, robroot_in_world=None, payload_kg=0.0):
    """Adds to `doc` a new Robot::TrajectoryObject (`name`, default trajectory.Name + "_accura")
    holding the trajectory compensated with the calibrated model and densified so that the
    real robot's predicted path error is below tol_mm (mm). Returns (object, summary dict).
    robroot_in_world and payload_kg as load_model (used when `model`, a loaded model, is None)."""
    own = model is None
    if own:
        model = load_model(robot, model_path, plugin_lib, payload_kg=payload_kg, robroot_in_world=robroot_in_world)
    try:
        summary = {"tol_mm": tol_mm, "max_error_uncompensated_mm": 0.0, "max_error_before_mm": 0.0,
                   "max_error_after_mm": 0.0, "points_added": 0}
        if check:
            summary["kinematics_mm"], summary["kinematics_deg"] = check_kinematics(doc, robot, model)
        wps = trajectory.Trajectory.Waypoints
        pose = [placement_to_xyzabc(w.Pos) for w in wps]
        joints = arm_joints(robot, wps)
        out = []
        for start, motions in _runs(wps):
            w0 = wps[start]
            # a PTP keeps the arm's configuration (S/T) there; a path starting elsewhere: any
            st = model.joint_configuration(joints[start]) if w0.Type == "PTP" else (None, None)
            if not motions:
                r = model.compensate_pose(pose[start], status=st[0], turn=st[1])
                out.append(_waypoint(r.command, w0, w0.Name))
                continue
            path = [("LIN", pose[m[1]]) if m[0] == "LIN" else ("CIRC", pose[m[1]], pose[m[2]]) for m in motions]
            res, points, reports = model.compensate_path(pose[start], path, tol_mm=tol_mm, start_status=st[0],
                                                         start_turn=st[1])
            out.append(_waypoint(res.start_command, w0, w0.Name))
            for key in ("max_error_uncompensated_mm", "max_error_before_mm", "max_error_after_mm"):
                summary[key] = max(summary[key], getattr(res, key))
            summary["points_added"] += res.points_added
            added = {}
            for p in points:
                m = motions[p.motion]
                end_wp = wps[m[-1]]
                if p.inserted:
                    added[p.motion] = added.get(p.motion, 0) + 1
                    label = "%s_a%d" % (end_wp.Name, added[p.motion])
                else:
                    label = end_wp.Name
                if m[0] == "CIRC":
                    out.append(_waypoint(p.aux, wps[m[1]], label + "_aux", "CIRC"))
                    out.append(_waypoint(p.end, end_wp, label, "CIRC"))
                else:
                    out.append(_waypoint(p.end, end_wp, label, "LIN"))
        obj = doc.addObject("Robot::TrajectoryObject", name or (trajectory.Name + "_accura"))
        obj.Trajectory = Robot.Trajectory(out)
        summary["waypoints_in"] = len(wps)
        summary["waypoints_out"] = len(out)
        doc.recompute()
        return obj, summary
    finally:
        if own:
            model.close()


def export_krl(trajectory, src_path, tool, base=(0, 0, 0, 0, 0, 0), program_name=None, plugin_lib=None, robot=None,
               model=None):
    """Writes the trajectory as a KUKA KRL program (src_path and the .dat next to it) with the
    plug-in's program writer (accura_write_program: accura's KRL writer, 0.1 um and 1e-5 deg,
    $BASE and $TOOL set so that the program says its frames, each file through a temporary file
    renamed into place). Waypoint types: PTP, LIN, and CIRC pairs (auxiliary point, end point);
    Cont -> C_PTP / C_DIS; Velocity (mm/s) -> $VEL.CP of LIN / CIRC. With `robot` (the FreeCAD
    robot) and `model` (its loaded model, load_model) every PTP carries the S/T of the arm's joint
    values there (arm_joints), so that the controller takes the arm's configuration; without them
    the PTPs have no S/T (the controller keeps its current one)."""
    if (robot is None) != (model is None):
        raise AccuraFreeCADError("export_krl: give both robot (the FreeCAD robot) and model (load_model) for the PTPs' "
                                 "S/T, or neither")
    wps = trajectory.Trajectory.Waypoints
    joints = arm_joints(robot, wps) if robot is not None else [None] * len(wps)
    motions, i = [], 0
    while i < len(wps):
        w = wps[i]
        p = placement_to_xyzabc(w.Pos)
        if w.Type == "PTP":
            motions.append(("PTP", p, w.Cont, joints[i]))
            i += 1
        elif w.Type == "LIN":
            motions.append(("LIN", p, w.Cont, w.Velocity / 1000.0))
            i += 1
        elif w.Type == "CIRC":
            if i + 1 >= len(wps) or wps[i + 1].Type != "CIRC":
                raise AccuraFreeCADError("waypoint %d (%s): a CIRC waypoint must be followed by its end point (CIRC)" % (i, w.Name))
            e = wps[i + 1]
            motions.append(("CIRC", p, placement_to_xyzabc(e.Pos), e.Cont, w.Velocity / 1000.0))
            i += 2
        else:
            raise AccuraFreeCADError("waypoint %d (%s): type %s cannot be exported (PTP, LIN, CIRC)" % (i, w.Name, w.Type))
    if model is not None:
        model.write_program(src_path, motions, tool, base, program_name)
    else:
        with accura_plugin.Plugin(plugin_lib).handle() as h:
            h.write_program(src_path, motions, tool, base, program_name)
    return src_path, os.path.splitext(src_path)[0] + ".dat"
