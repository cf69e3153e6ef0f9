#!/usr/bin/env python3
"""ctest freecad_macro_options: the FreeCAD GUI macro's options (robroot_in_world, payload) are
checked with messages to the letter. The macro runs with stand-ins for FreeCAD's GUI modules and
an empty selection (it warns and stops); its parsers are then called directly."""
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
sys.exit(1 if failures else 0)
