#!/usr/bin/env python3
"""Example and test of the Python wrapper (run by ctest as plugin_python): loads the plug-in
with ctypes, compensates poses, a seam (LIN, CIRC, LIN) and a KRL program, and checks the
numbers. Exit status 0 when every check holds.

    python3 example.py --lib build/plugin/libaccura_plugin.so --model tests/data/plugin/kr16_calibrated.xml
"""
import argparse
import math
import os
import sys
import tempfile

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import accura_plugin  # noqa: E402

failures = []


def check(cond, what):
    if not cond:
        failures.append(what)
        print("FAILED:", what, file=sys.stderr)


def rotation(p):
    """R = Rz(A) Ry(B) Rx(C) of a pose (deg)."""
    a, b, c = (math.radians(v) for v in p[3:])
    ca, sa, cb, sb, cc, sc = math.cos(a), math.sin(a), math.cos(b), math.sin(b), math.cos(c), math.sin(c)
    return [[ca * cb, ca * sb * sc - sa * cc, ca * sb * cc + sa * sc],
            [sa * cb, sa * sb * sc + ca * cc, sa * sb * cc - ca * sc],
            [-sb, cb * sc, cb * cc]]


def distance_mm(p, q):
    return math.dist(p[:3], q[:3])


def rotation_diff(p, q):
    """Largest element difference of the rotation matrices (about the angle in rad when small)."""
    R, S = rotation(p), rotation(q)
    return max(abs(R[i][j] - S[i][j]) for i in range(3) for j in range(3))


SEAM_PROGRAM = """DEF seam( )
$BASE = {X 0, Y 0, Z 0, A 0, B 0, C 0}
$TOOL = {X 20, Y 0, Z 250, A 0, B -30, C 0}
PTP {X 1100, Y -250, Z 500, A 0, B 180, C 0}
LIN {X 1100, Y -50, Z 500, A 0, B 180, C 0}
CIRC {X 1180, Y 30, Z 500, A 0, B 180, C 0}, {X 1260, Y -50, Z 500, A 0, B 180, C 0}
LIN {X 1260, Y -250, Z 500, A 0, B 180, C 0}
END
"""


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--lib", help="libaccura_plugin.so (default: $ACCURA_PLUGIN_LIB, else the installed PREFIX/lib one)")
    ap.add_argument("--model", required=True, help="a calibrated model (tests/data/plugin/kr16_calibrated.xml)")
    a = ap.parse_args()

    plugin = accura_plugin.Plugin(a.lib)
    print("accura plug-in %d.%d.%d, ABI %d" % (plugin.version + (plugin.abi_version,)))
    check(plugin.abi_version == accura_plugin.ABI_VERSION, "ABI")

    # a library that cannot be loaded: ERROR_INPUT, and the message says how to name it (eyes F11)
    try:
        accura_plugin.Plugin("/nonexistent/libaccura_plugin.so")
        check(False, "loading a missing library must fail")
    except accura_plugin.AccuraError as e:
        check(e.status == accura_plugin.ERROR_INPUT and e.message.startswith(
            "cannot load the accura plug-in library '/nonexistent/libaccura_plugin.so' (") and e.message.endswith(
            "): give its path (Plugin(path), or ACCURA_PLUGIN_LIB=/path/to/libaccura_plugin.so)"), "library message: %s" % e)

    # a missing file: ERROR_INPUT, and the message names the path
    missing = "/nonexistent/kr16_calibrated.xml"
    try:
        plugin.load(missing)
        check(False, "loading a missing file must fail")
    except accura_plugin.AccuraError as e:
        print("missing file:", e)
        check(e.status == accura_plugin.ERROR_INPUT, "status of a missing file: %s" % e.name)
        check(missing in e.message, "the message names the path")

    with plugin.load(a.model) as model:
        info = model.info()
        check(info.dof == 6 and info.robot_name == b"KUKA KR 16", "info: %d %r" % (info.dof, info.robot_name))

        # one pose: the real robot at q' reaches the target; the controller at q' is at the command
        target = (1100, -250, 500, 0, 180, 0)
        r = model.compensate_pose(target, status=2)
        real = model.forward_kinematics(r.q_real, accura_plugin.REAL)
        ctrl = model.forward_kinematics(r.q_real, accura_plugin.CONTROLLER)
        print("pose: correction %.4f mm, command %s" % (r.correction_mm, ", ".join("%.4f" % v for v in r.command)))
        check(distance_mm(real, target) < 1e-6 and rotation_diff(real, target) < 1e-9, "FK_real(q') = target")
        check(distance_mm(ctrl, r.command) < 1e-6 and rotation_diff(ctrl, r.command) < 1e-9, "FK_controller(q') = command")
        check(0.2 < r.correction_mm < 8, "correction %.4f mm" % r.correction_mm)
        check(abs(r.correction_mm - distance_mm(r.command, target)) < 1e-9, "correction_mm = |command - target|")

        # a list with one unreachable pose: per-pose statuses
        rs = model.compensate_poses([target, (5000, 0, 500, 0, 180, 0)], raise_on_failure=False)
        check(rs[0].ok and rs[0].command == r.command, "list = single call")
        check(rs[1].status == accura_plugin.ERROR_UNREACHABLE, "unreachable: %d" % rs[1].status)
        try:
            model.compensate_poses([target, (5000, 0, 500, 0, 180, 0)])
            check(False, "raise_on_failure")
        except accura_plugin.AccuraError as e:
            check(e.status == accura_plugin.ERROR_UNREACHABLE and "pose 1" in e.message, "message: %s" % e.message)

        # the seam: LIN 200 mm, half circle r = 80 mm, LIN 200 mm
        tol_mm = 0.05
        res, points, reports = model.compensate_path(
            (1100, -250, 500, 0, 180, 0),
            [("LIN", (1100, -50, 500, 0, 180, 0)),
             ("CIRC", (1180, 30, 500, 0, 180, 0), (1260, -50, 500, 0, 180, 0)),
             ("LIN", (1260, -250, 500, 0, 180, 0))], tol_mm=tol_mm)
        print("seam: %d points (%d added); path error %.4f mm as programmed -> %.4f mm -> %.4f mm with the points" %
              (res.n_points, res.points_added, res.max_error_uncompensated_mm, res.max_error_before_mm,
               res.max_error_after_mm))
        check(res.max_error_after_mm <= tol_mm and res.max_error_bound_mm <= tol_mm, "tolerance met")
        check(res.max_error_uncompensated_mm > 0.5, "uncompensated about a millimetre off")
        check(len(points) == 3 + res.points_added, "points = motions + added")
        check(abs(reports[1].length_mm - 80 * math.pi) < 1e-3, "CIRC length %.6f" % reports[1].length_mm)
        check([p.motion for p in points if not p.inserted] == [0, 1, 2], "one end point per motion")

        # a KRL program, compensated into another directory; the input is left alone
        with tempfile.TemporaryDirectory() as d:
            src = os.path.join(d, "seam.src")
            with open(src, "w") as f:
                f.write(SEAM_PROGRAM)
            out = os.path.join(d, "out")
            s = model.compensate_program(src, out, tol_mm=tol_mm)
            print("program: %d targets corrected (max %.4f mm), %d point(s) added, path error %.4f -> %.4f mm; wrote %s" %
                  (s.targets_corrected, s.max_correction_mm, s.points_added, s.max_error_uncompensated_mm,
                   s.max_error_after_mm, s.output_path.decode()))
            check(s.targets_corrected >= 4, "targets corrected: %d (PTP, LIN, CIRC, LIN)" % s.targets_corrected)
            check(s.segments == 3 and s.max_error_after_mm <= tol_mm, "segments and tolerance")
            check(s.points_added == res.points_added, "the same points as the path call: %d vs %d" %
                  (s.points_added, res.points_added))
            check(open(src).read() == SEAM_PROGRAM, "input unchanged")
            text = open(s.output_path.decode()).read()
            motions = [ln for ln in text.splitlines() if ln.split(" ")[0] in ("PTP", "LIN", "CIRC")]
            check(len(motions) == 4 + s.points_added, "inserted motions written: %d lines" % len(motions))
            # a PTP written with the arm's joints carries their S/T (KUKA's HOME {0, -90, 90, 0, 0, 0}: S 2, T 2;
            # A5 < 0 adds S bit 2 and T bit 4)
            home, flip = (0, -90, 90, 0, 0, 0), (10, -60, 80, 20, -45, 30)
            check(model.joint_configuration(home) == (2, 2), "S/T of HOME: %r" % (model.joint_configuration(home),))
            check(model.joint_configuration(flip) == (6, 18), "S/T with A5 < 0: %r" % (model.joint_configuration(flip),))
            ptp = os.path.join(d, "ptp.src")
            torch = (20, 0, 250, 0, -30, 0)  # the model's tool: the program tool of its poses
            model.write_program(ptp, [("PTP", model.forward_kinematics(q), False, q) for q in (home, flip)], tool=torch)
            ptps = [ln for ln in open(ptp).read().splitlines() if ln.startswith("PTP")]
            check(len(ptps) == 2 and ptps[0].endswith(",S 2,T 2}") and ptps[1].endswith(",S 6,T 18}"), "PTP S/T: %r" % ptps)
            try:
                model.compensate_program(src, d)  # would overwrite the input
                check(False, "overwriting the input must fail")
            except accura_plugin.AccuraError as e:
                check(e.status == accura_plugin.ERROR_INPUT and "overwrite" in e.message, "overwrite: %s" % e.message)

    if failures:
        print("%d check(s) failed" % len(failures), file=sys.stderr)
        return 1
    print("python example: all checks passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
