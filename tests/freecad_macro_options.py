#!/usr/bin/env python3
"""ctest freecad_macro_options: the FreeCAD GUI macro's options (robroot_in_world, payload) are
checked with messages to the letter. The macro runs with stand-ins for FreeCAD's GUI modules and
an empty selection (it warns and stops); its parsers are then called directly. Then it runs again
with a robot and a trajectory selected (issue 17): the KRL export gets the robot and the loaded
model, so that every PTP carries the S/T of the arm's joints, before the model is closed."""
import sys
import types

sys.dont_write_bytecode = True
warnings = []
gui = types.SimpleNamespace(Selection=types.SimpleNamespace(getSelection=lambda: []))
qt = types.SimpleNamespace(QMessageBox=types.SimpleNamespace(warning=lambda *a: warnings.append(a[2]),
                                                             critical=lambda *a: warnings.append(a[2])))
sys.modules.update({"FreeCAD": types.ModuleType("FreeCAD"), "FreeCADGui": gui,
                    "PySide": types.SimpleNamespace(QtGui=qt), "accura_freecad": types.ModuleType("accura_freecad")})
ns = {"__file__": sys.argv[1]}
exec(compile(open(sys.argv[1]).read(), sys.argv[1], "exec"), ns)
failures = []


def expect(cond, what):
    if not cond:
        failures.append(what)
        print("FAILED:", what, file=sys.stderr)


def error_of(f, text):
    try:
        f(text)
    except ValueError as e:
        return str(e)
    return None


expect(warnings == ["Select one robot and one trajectory."], "empty selection: %r" % warnings)
expect(ns["parse_robroot"]("") is None, "empty robroot: the model's <base>")
expect(ns["parse_robroot"](" 2400,-1700,-600,30,0.4,-0.3 ") == (2400, -1700, -600, 30, 0.4, -0.3), "six values")
expect(error_of(ns["parse_robroot"], "2400,-1700,-600") ==
       "robot base in the model's world: expected six values x,y,z,A,B,C (mm, deg), found 3 in '2400,-1700,-600'",
       "three values: %r" % error_of(ns["parse_robroot"], "2400,-1700,-600"))
expect(error_of(ns["parse_robroot"], "1,2,3,4,5,nan") == "robot base in the model's world: expected a number, found 'nan'",
       "nan: %r" % error_of(ns["parse_robroot"], "1,2,3,4,5,nan"))
expect(ns["parse_payload"]("8") == 8.0, "payload 8 kg")
expect(error_of(ns["parse_payload"], "inf") == "payload: expected a number in [0, 10000] (kg), found 'inf'",
       "inf: %r" % error_of(ns["parse_payload"], "inf"))
expect(error_of(ns["parse_payload"], "-1") == "payload: expected a number in [0, 10000] (kg), found '-1'", "negative")

# a robot and a trajectory selected: what the macro hands accura_freecad (stand-in), in order
calls = []
robot = types.SimpleNamespace(TypeId="Robot::RobotObject", Tool="TOOL")
trajectory = types.SimpleNamespace(TypeId="Robot::TrajectoryObject", Name="Seam")


class Loaded:
    def close(self):
        calls.append(("close",))


loaded = Loaded()
af = types.ModuleType("accura_freecad")
af.placement_to_xyzabc = lambda p: (20, 0, 250, 0, -30, 0) if p == "TOOL" else None
af.load_model = lambda r, m, **kw: calls.append(("load_model", r, m, kw)) or loaded
af.compensate_trajectory = lambda doc, r, t, m, **kw: (calls.append(("compensate", r, t, kw["model"])) or
                                                        ("NEW", {"waypoints_in": 6, "waypoints_out": 10,
                                                                 "max_error_uncompensated_mm": 1.5,
                                                                 "max_error_after_mm": 0.04}))
af.export_krl = lambda obj, src, **kw: calls.append(("export_krl", obj, src, kw))
gui.Selection.getSelection = lambda: [robot, trajectory]
qt.QFileDialog = types.SimpleNamespace(getOpenFileName=lambda *a: ("/m/kr16_calibrated.xml", ""),
                                       getSaveFileName=lambda *a: ("/o/seam_accura.src", ""))
qt.QInputDialog = types.SimpleNamespace(getText=lambda *a, **kw: (kw["text"], True))
app = sys.modules["FreeCAD"]
app.ActiveDocument = "DOC"
app.Console = types.SimpleNamespace(PrintMessage=lambda text: calls.append(("print", text)))
sys.modules["accura_freecad"] = af
warnings.clear()
exec(compile(open(sys.argv[1]).read(), sys.argv[1], "exec"), {"__file__": sys.argv[1]})
expect(warnings == [], "selection: no warning or error: %r" % warnings)
names = [c[0] for c in calls]
expect(names == ["load_model", "compensate", "export_krl", "close", "print"], "calls in order: %r" % names)
if names[:4] == ["load_model", "compensate", "export_krl", "close"]:
    expect(calls[0][3] == {"payload_kg": 0.0, "robroot_in_world": None}, "load options: %r" % (calls[0][3],))
    expect(calls[1][3] is loaded, "compensated with the loaded model")
    expect(calls[2][1:3] == ("NEW", "/o/seam_accura.src"), "exported the compensated trajectory: %r" % (calls[2][1:3],))
    expect(calls[2][3] == {"tool": (20, 0, 250, 0, -30, 0), "robot": robot, "model": loaded},
           "export with the robot and the loaded model (PTP S/T): %r" % (calls[2][3],))
sys.exit(1 if failures else 0)
