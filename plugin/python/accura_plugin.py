"""A thin ctypes wrapper of the accura plug-in (libaccura_plugin.so, plugin/include/accura_plugin.h).

Units: mm and deg. Poses are (x, y, z, A, B, C) tuples with R = Rz(A) Ry(B) Rx(C), in the
program's base frame ($BASE) with the program's tool ($TOOL); see docs/plugin.md.

    from accura_plugin import Plugin
    plugin = Plugin("/path/to/libaccura_plugin.so")      # or $ACCURA_PLUGIN_LIB
    with plugin.load("model.xml", program_tool=(20, 0, 250, 0, -30, 0)) as model:
        r = model.compensate_pose((1100, -250, 500, 0, 180, 0), status=2)
        print(r.command, r.correction_mm)

Every failing call raises AccuraError (its .status, .name and the library's message).
"""
import ctypes
import os

ABI_VERSION = 2
MAX_JOINTS = 12

OK = 0
ERROR_NULL_ARGUMENT = 1
ERROR_INVALID_ARGUMENT = 2
ERROR_BUFFER_TOO_SMALL = 3
ERROR_INPUT = 4
ERROR_UNREACHABLE = 5
ERROR_JOINT_LIMITS = 6
ERROR_SINGULAR = 7
ERROR_NO_CONFIGURATION = 8
ERROR_NOT_CONVERGED = 9
ERROR_NUMERICAL = 10
ERROR_OUT_OF_MEMORY = 11
ERROR_INTERNAL = 12

LIN = 0
CIRC = 1
PTP = 2
CONTROLLER = 0
REAL = 1


class AccuraError(Exception):
    """A call of the plug-in failed: status (int), name ("ACCURA_ERROR_INPUT"), message."""

    def __init__(self, status, name, message):
        super().__init__("%s: %s" % (name, message))
        self.status = status
        self.name = name
        self.message = message


class Pose(ctypes.Structure):
    _fields_ = [(n, ctypes.c_double) for n in ("x_mm", "y_mm", "z_mm", "a_deg", "b_deg", "c_deg")]

    @staticmethod
    def of(p):
        if len(p) != 6:
            raise ValueError("a pose is x, y, z (mm), A, B, C (deg): 6 numbers, got %d" % len(p))
        return Pose(*[float(v) for v in p])

    def tuple(self):
        return (self.x_mm, self.y_mm, self.z_mm, self.a_deg, self.b_deg, self.c_deg)


class Configuration(ctypes.Structure):
    _fields_ = [("status", ctypes.c_int), ("turn", ctypes.c_int)]


class LoadOptions(ctypes.Structure):
    _fields_ = [("struct_size", ctypes.c_size_t), ("controller_model", ctypes.c_char_p),
                ("has_robroot_in_world", ctypes.c_int), ("robroot_in_world", Pose),
                ("has_robroot_in_kukaworld", ctypes.c_int), ("robroot_in_kukaworld", Pose),
                ("has_program_base", ctypes.c_int), ("program_base", Pose),
                ("has_program_tool", ctypes.c_int), ("program_tool", Pose),
                ("payload_kg", ctypes.c_double), ("temp_c", ctypes.c_double)]


class ModelInfo(ctypes.Structure):
    _fields_ = [("dof", ctypes.c_int), ("robot_name", ctypes.c_char * 128), ("robroot_in_world", Pose),
                ("calibrated_base_in_world", Pose), ("lower", ctypes.c_double * MAX_JOINTS),
                ("upper", ctypes.c_double * MAX_JOINTS)]


class PoseResult(ctypes.Structure):
    _fields_ = [("status", ctypes.c_int), ("command_", Pose), ("configuration", Configuration),
                ("configuration_changed", ctypes.c_int), ("correction_mm", ctypes.c_double),
                ("correction_deg", ctypes.c_double), ("dof", ctypes.c_int),
                ("q_real_", ctypes.c_double * MAX_JOINTS)]

    @property
    def command(self):
        return self.command_.tuple()

    @property
    def q_real(self):
        return tuple(self.q_real_[:self.dof])

    @property
    def ok(self):
        return self.status == OK


class PathMotion(ctypes.Structure):
    _fields_ = [("type", ctypes.c_int), ("aux", Pose), ("end", Pose)]


class PathPoint(ctypes.Structure):
    _fields_ = [("type", ctypes.c_int), ("aux_", Pose), ("end_", Pose), ("configuration", Configuration),
                ("motion", ctypes.c_int), ("inserted", ctypes.c_int)]

    @property
    def end(self):
        return self.end_.tuple()

    @property
    def aux(self):
        return self.aux_.tuple()


class MotionReport(ctypes.Structure):
    _fields_ = [(n, ctypes.c_double) for n in ("length_mm", "max_error_uncompensated_mm", "max_error_before_mm",
                                                 "max_error_after_mm", "max_error_bound_mm")] + \
               [("points_added", ctypes.c_int)]


class PathResult(ctypes.Structure):
    _fields_ = [("start_command_", Pose), ("start_configuration", Configuration), ("n_points", ctypes.c_size_t)] + \
               [(n, ctypes.c_double) for n in ("max_error_uncompensated_mm", "max_error_before_mm",
                                                 "max_error_after_mm", "max_error_bound_mm")] + \
               [("points_added", ctypes.c_int), ("failed_motion", ctypes.c_int)]

    @property
    def start_command(self):
        return self.start_command_.tuple()


class ProgramOptions(ctypes.Structure):
    _fields_ = [("struct_size", ctypes.c_size_t), ("dat_path", ctypes.c_char_p), ("config_path", ctypes.c_char_p),
                ("tol_mm", ctypes.c_double), ("json_report_path", ctypes.c_char_p)]


class ProgramSummary(ctypes.Structure):
    _fields_ = [("targets_corrected", ctypes.c_int), ("points_added", ctypes.c_int), ("segments", ctypes.c_int),
                ("warnings", ctypes.c_int)] + \
               [(n, ctypes.c_double) for n in ("max_correction_mm", "rms_correction_mm", "max_correction_deg",
                                                 "max_error_uncompensated_mm", "max_error_before_mm",
                                                 "max_error_after_mm")] + \
               [("output_path", ctypes.c_char * 1024)]


class CheckOptions(ctypes.Structure):
    _fields_ = [("struct_size", ctypes.c_size_t), ("dat_path", ctypes.c_char_p), ("config_path", ctypes.c_char_p),
                ("as_written", ctypes.c_int), ("use_cell_thresholds", ctypes.c_int),
                ("joint_margin_deg", ctypes.c_double), ("singular_threshold", ctypes.c_double),
                ("min_clearance_mm", ctypes.c_double)]


class CheckViolation(ctypes.Structure):
    _fields_ = [("kind", ctypes.c_int), ("motion_index", ctypes.c_int), ("line", ctypes.c_int), ("column", ctypes.c_int),
                ("on_path", ctypes.c_int), ("s", ctypes.c_double), ("p_world_tcp_mm", ctypes.c_double * 3),
                ("value", ctypes.c_double), ("limit", ctypes.c_double), ("joint", ctypes.c_int),
                ("message", ctypes.c_char * 512)]


class CheckSummary(ctypes.Structure):
    _fields_ = [("passed", ctypes.c_int), ("n_violations", ctypes.c_size_t), ("unchecked", ctypes.c_int),
                ("samples", ctypes.c_int), ("min_clearance_mm", ctypes.c_double), ("min_sigma", ctypes.c_double),
                ("min_joint_margin", ctypes.c_double)]


class Joint(ctypes.Structure):
    _fields_ = [("prismatic", ctypes.c_int), ("a_mm", ctypes.c_double), ("alpha_deg", ctypes.c_double),
                ("d_mm", ctypes.c_double), ("theta0_deg", ctypes.c_double), ("direction", ctypes.c_int),
                ("lower", ctypes.c_double), ("upper", ctypes.c_double)]


class ProgramMotion(ctypes.Structure):
    _fields_ = [("type", ctypes.c_int), ("aux", Pose), ("end", Pose), ("approximate", ctypes.c_int),
                ("vel_m_s", ctypes.c_double), ("n_joints", ctypes.c_int), ("joints", ctypes.c_double * MAX_JOINTS)]


class WriteOptions(ctypes.Structure):
    _fields_ = [("struct_size", ctypes.c_size_t), ("program_name", ctypes.c_char_p), ("tool", Pose), ("base", Pose)]


def _installed_library():
    """PREFIX/lib/libaccura_plugin.so when this wrapper is installed as PREFIX/share/accura/python/ (cmake --install);
    None otherwise."""
    here = os.path.dirname(os.path.abspath(__file__))
    for lib in ("lib", "lib64"):
        p = os.path.join(here, os.pardir, os.pardir, os.pardir, lib, "libaccura_plugin.so")
        if os.path.exists(p):
            return os.path.normpath(p)
    return None


def _bytes(s):
    return None if s is None else os.fsencode(s)


class Plugin:
    """The loaded library. `path`: the .so (default: $ACCURA_PLUGIN_LIB, else the installed PREFIX/lib next to this
    wrapper's PREFIX/share/accura/python, else libaccura_plugin.so on the loader's path). Raises AccuraError when it
    cannot be loaded (naming ACCURA_PLUGIN_LIB) or its ABI is not this wrapper's."""

    def __init__(self, path=None):
        path = path or os.environ.get("ACCURA_PLUGIN_LIB") or _installed_library() or "libaccura_plugin.so"
        try:
            self.lib = ctypes.CDLL(path)
        except OSError as e:
            raise AccuraError(ERROR_INPUT, "ACCURA_ERROR_INPUT",
                              "cannot load the accura plug-in library '%s' (%s): give its path (Plugin(path), or "
                              "ACCURA_PLUGIN_LIB=/path/to/libaccura_plugin.so)" % (path, e)) from None
        self.path = path
        L = self.lib
        P = ctypes.POINTER
        vp = ctypes.c_void_p
        sigs = {
            "accura_version": [P(ctypes.c_int)] * 4,
            "accura_status_name": [ctypes.c_int, P(ctypes.c_char_p)],
            "accura_last_error": [vp, P(ctypes.c_char_p)],
            "accura_model_create": [P(vp)],
            "accura_model_free": [vp],
            "accura_load_options_init": [P(LoadOptions), ctypes.c_size_t],
            "accura_model_load": [vp, ctypes.c_char_p, P(LoadOptions)],
            "accura_model_get_info": [vp, P(ModelInfo)],
            "accura_forward_kinematics": [vp, ctypes.c_int, P(ctypes.c_double), ctypes.c_size_t, P(Pose)],
            "accura_joint_configuration": [vp, P(ctypes.c_double), ctypes.c_size_t, P(Configuration)],
            "accura_compensate_pose": [vp, P(Pose), P(Configuration), P(PoseResult)],
            "accura_compensate_poses": [vp, P(Pose), P(Configuration), ctypes.c_size_t, ctypes.c_int, P(PoseResult),
                                        P(ctypes.c_size_t)],
            "accura_compensate_path": [vp, P(Pose), P(Configuration), P(PathMotion), ctypes.c_size_t, ctypes.c_double,
                                       P(PathPoint), ctypes.c_size_t, P(PathResult), P(MotionReport)],
            "accura_program_options_init": [P(ProgramOptions), ctypes.c_size_t],
            "accura_compensate_program": [vp, ctypes.c_char_p, ctypes.c_char_p, P(ProgramOptions), P(ProgramSummary)],
            "accura_compensate_program_modules": [vp, ctypes.c_char_p, ctypes.c_char_p, P(ProgramOptions),
                                                  P(ctypes.c_char_p), ctypes.c_size_t, P(ProgramSummary)],
            "accura_model_get_joints": [vp, P(Joint), ctypes.c_size_t, P(ctypes.c_size_t)],
            "accura_write_options_init": [P(WriteOptions), ctypes.c_size_t],
            "accura_write_program": [vp, ctypes.c_char_p, P(ProgramMotion), ctypes.c_size_t, P(WriteOptions)],
            "accura_write_file": [vp, ctypes.c_char_p, ctypes.c_char_p, ctypes.c_size_t],
            "accura_check_options_init": [P(CheckOptions), ctypes.c_size_t],
            "accura_check_program": [vp, ctypes.c_char_p, ctypes.c_char_p, P(CheckOptions), P(CheckSummary),
                                     P(CheckViolation), ctypes.c_size_t],
        }
        for name, args in sigs.items():
            f = getattr(L, name)
            f.argtypes = args
            f.restype = ctypes.c_int
        v = [ctypes.c_int(-1) for _ in range(4)]
        L.accura_version(*[ctypes.byref(x) for x in v])
        self.version = tuple(x.value for x in v[:3])
        self.abi_version = v[3].value
        if self.abi_version != ABI_VERSION:
            raise AccuraError(ERROR_INVALID_ARGUMENT, "ACCURA_ERROR_INVALID_ARGUMENT",
                              "%s has ABI %d, this wrapper speaks ABI %d" % (path, self.abi_version, ABI_VERSION))

    def status_name(self, status):
        name = ctypes.c_char_p()
        self.lib.accura_status_name(status, ctypes.byref(name))
        return name.value.decode()

    def load(self, calibrated_model, controller_model=None, robroot_in_world=None, robroot_in_kukaworld=None,
             program_base=None, program_tool=None, payload_kg=0.0, temp_c=20.0):
        """A Model: the calibrated model file (or bundled robot name) with its frames (accura_model_load)."""
        return Model(self, calibrated_model, controller_model, robroot_in_world, robroot_in_kukaworld, program_base,
                     program_tool, payload_kg, temp_c)

    def handle(self):
        """A Model without a loaded model: for write_program and write_file (close() or `with` frees it)."""
        return Model(self, None, None, None, None, None, None, 0.0, 20.0)


class Model:
    """A loaded model (an accura_model handle; calibrated_model None: none loaded). Usable from several threads
    (close() too: calls running on other threads finish, later ones raise); close() or `with` frees it."""

    def __init__(self, plugin, calibrated_model, controller_model, robroot_in_world, robroot_in_kukaworld,
                 program_base, program_tool, payload_kg, temp_c):
        self.plugin = plugin
        self.lib = plugin.lib
        self.handle = ctypes.c_void_p()
        self._check(self.lib.accura_model_create(ctypes.byref(self.handle)), no_handle=True)
        if calibrated_model is None:
            return
        try:
            o = LoadOptions()
            self._check(self.lib.accura_load_options_init(ctypes.byref(o), ctypes.sizeof(o)), no_handle=True)
            o.controller_model = _bytes(controller_model)
            for field, value in (("robroot_in_world", robroot_in_world), ("robroot_in_kukaworld", robroot_in_kukaworld),
                                 ("program_base", program_base), ("program_tool", program_tool)):
                if value is not None:
                    setattr(o, "has_" + field, 1)
                    setattr(o, field, Pose.of(value))
            o.payload_kg = payload_kg
            o.temp_c = temp_c
            self._check(self.lib.accura_model_load(self.handle, _bytes(calibrated_model), ctypes.byref(o)))
        except BaseException:
            self.close()
            raise

    def close(self):
        if self.handle:
            self.lib.accura_model_free(self.handle)
            self.handle = ctypes.c_void_p()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __del__(self):
        self.close()

    def last_error(self, no_handle=False):
        """The message of this thread's last failed call on the handle (no_handle, or no handle: of its last
        failed call without a live handle, e.g. an *_options_init)."""
        msg = ctypes.c_char_p()
        self.lib.accura_last_error(None if no_handle or not self.handle else self.handle, ctypes.byref(msg))
        return (msg.value or b"").decode(errors="replace")

    def _check(self, status, no_handle=False):
        if status != OK:
            raise AccuraError(status, self.plugin.status_name(status), self.last_error(no_handle))

    def info(self):
        i = ModelInfo()
        self._check(self.lib.accura_model_get_info(self.handle, ctypes.byref(i)))
        return i

    def joints(self):
        """The nominal robot's joints (Joint: prismatic, a_mm, alpha_deg, d_mm, theta0_deg, direction, lower, upper)."""
        arr = (Joint * MAX_JOINTS)()
        n = ctypes.c_size_t()
        self._check(self.lib.accura_model_get_joints(self.handle, arr, MAX_JOINTS, ctypes.byref(n)))
        return list(arr[:n.value])

    def write_program(self, path, motions, tool, base=(0, 0, 0, 0, 0, 0), program_name=None):
        """Writes a new program (.src: KRL with its .dat; .xml: accura's XML) with accura's writer, each file through
        a temporary file renamed into place. motions: ("PTP", end, approximate[, joints]), ("LIN", end, approximate,
        vel_m_s) or ("CIRC", aux, end, approximate, vel_m_s) tuples; a PTP's joints (the arm's joint values at end, deg;
        None: none) give its S/T (needs a loaded model); tool, base: $TOOL and $BASE (x, y, z, A, B, C)."""
        arr = (ProgramMotion * max(len(motions), 1))()
        for i, m in enumerate(motions):
            kind = m[0].upper()
            if kind == "PTP" and len(m) in (3, 4):
                q = list(m[3]) if len(m) == 4 and m[3] is not None else []
                if len(q) > MAX_JOINTS:
                    raise ValueError("motion %d: at most %d joint values, found %d" % (i, MAX_JOINTS, len(q)))
                arr[i] = ProgramMotion(PTP, Pose(), Pose.of(m[1]), 1 if m[2] else 0, 0.0, len(q),
                                       (ctypes.c_double * MAX_JOINTS)(*[float(v) for v in q]))
            elif kind == "LIN" and len(m) == 4:
                arr[i] = ProgramMotion(LIN, Pose(), Pose.of(m[1]), 1 if m[2] else 0, m[3])
            elif kind == "CIRC" and len(m) == 5:
                arr[i] = ProgramMotion(CIRC, Pose.of(m[1]), Pose.of(m[2]), 1 if m[3] else 0, m[4])
            else:
                raise ValueError("motion %d: expected ('PTP', end, approx[, joints]), ('LIN', end, approx, vel_m_s) or "
                                 "('CIRC', aux, end, approx, vel_m_s), found %r" % (i, m))
        o = WriteOptions()
        self._check(self.lib.accura_write_options_init(ctypes.byref(o), ctypes.sizeof(o)))
        o.program_name = _bytes(program_name)
        o.tool = Pose.of(tool)
        o.base = Pose.of(base)
        self._check(self.lib.accura_write_program(self.handle, _bytes(path), arr, len(motions), ctypes.byref(o)))
        return path

    def write_file(self, path, text):
        """Writes text (str, UTF-8) to path through a temporary file renamed into place (accura's one writer)."""
        data = text.encode()
        self._check(self.lib.accura_write_file(self.handle, _bytes(path), data, len(data)))
        return path

    def forward_kinematics(self, q, which=CONTROLLER):
        """T_base_tcp (x, y, z, A, B, C) of the controller (nominal) or the REAL model at joints q (deg)."""
        arr = (ctypes.c_double * len(q))(*q)
        p = Pose()
        self._check(self.lib.accura_forward_kinematics(self.handle, which, arr, len(q), ctypes.byref(p)))
        return p.tuple()

    def joint_configuration(self, q):
        """(S, T) of joint values q (deg) by KUKA's rule: what a PTP must carry for the arm to take them."""
        arr = (ctypes.c_double * len(q))(*q)
        c = Configuration()
        self._check(self.lib.accura_joint_configuration(self.handle, arr, len(q), ctypes.byref(c)))
        return c.status, c.turn

    @staticmethod
    def _config(status, turn):
        if status is None and turn is None:
            return None
        return Configuration(-1 if status is None else status, -1 if turn is None else turn)

    def compensate_pose(self, target, status=None, turn=None):
        """The compensation of one pose: a PoseResult (.command, .q_real, .correction_mm, ...)."""
        r = PoseResult()
        c = self._config(status, turn)
        self._check(self.lib.accura_compensate_pose(self.handle, ctypes.byref(Pose.of(target)),
                                                    ctypes.byref(c) if c else None, ctypes.byref(r)))
        return r

    def compensate_poses(self, targets, configurations=None, continuous=False, raise_on_failure=True):
        """A list of PoseResults (each with its .status). configurations: None or (S, T) pairs (-1: any)."""
        n = len(targets)
        arr = (Pose * n)(*[Pose.of(t) for t in targets])
        cfg = None
        if configurations is not None:
            cfg = (Configuration * n)(*[Configuration(s, t) for s, t in configurations])
        res = (PoseResult * n)()
        n_ok = ctypes.c_size_t()
        st = self.lib.accura_compensate_poses(self.handle, arr, cfg, n, 1 if continuous else 0, res, ctypes.byref(n_ok))
        if raise_on_failure or st not in (ERROR_UNREACHABLE, ERROR_JOINT_LIMITS, ERROR_SINGULAR,
                                          ERROR_NO_CONFIGURATION, ERROR_NOT_CONVERGED):
            self._check(st)
        return list(res)

    def compensate_path(self, start, motions, tol_mm=0.05, start_status=None, start_turn=None):
        """Compensates and densifies a path. motions: ("LIN", end) or ("CIRC", aux, end) tuples, in order from
        `start`. Returns (PathResult, [PathPoint], [MotionReport])."""
        n = len(motions)
        arr = (PathMotion * max(n, 1))()
        for i, m in enumerate(motions):
            kind = m[0].upper()
            if kind == "LIN" and len(m) == 2:
                arr[i] = PathMotion(LIN, Pose(), Pose.of(m[1]))
            elif kind == "CIRC" and len(m) == 3:
                arr[i] = PathMotion(CIRC, Pose.of(m[1]), Pose.of(m[2]))
            else:
                raise ValueError("motion %d: expected ('LIN', end) or ('CIRC', aux, end), found %r" % (i, m))
        c = self._config(start_status, start_turn)
        result = PathResult()
        reports = (MotionReport * max(n, 1))()
        args = (self.handle, ctypes.byref(Pose.of(start)), ctypes.byref(c) if c else None, arr, n, tol_mm)
        capacity = 4 * n + 4
        while True:
            points = (PathPoint * capacity)()
            st = self.lib.accura_compensate_path(*args, points, capacity, ctypes.byref(result), reports)
            if st == ERROR_BUFFER_TOO_SMALL and result.n_points > capacity:
                capacity = result.n_points
                continue
            self._check(st)
            return result, list(points[:result.n_points]), list(reports[:n])

    def compensate_program(self, program, out_dir, tol_mm=0.05, dat=None, config=None, json_report=None, task_modules=()):
        """Compensates a program file (KRL .src, XML, RAPID module, URScript) into out_dir; returns a
        ProgramSummary. task_modules: for an ABB RAPID module, the other modules of its task
        (CalibData.mod, user.sys, ...), each only read (accura_compensate_program_modules)."""
        o = ProgramOptions()
        self._check(self.lib.accura_program_options_init(ctypes.byref(o), ctypes.sizeof(o)))
        o.tol_mm = tol_mm
        o.dat_path = _bytes(dat)
        o.config_path = _bytes(config)
        o.json_report_path = _bytes(json_report)
        s = ProgramSummary()
        if task_modules:
            paths = (ctypes.c_char_p * len(task_modules))(*[_bytes(m) for m in task_modules])
            self._check(self.lib.accura_compensate_program_modules(self.handle, _bytes(program), _bytes(out_dir),
                                                                   ctypes.byref(o), paths, len(task_modules),
                                                                   ctypes.byref(s)))
        else:
            self._check(self.lib.accura_compensate_program(self.handle, _bytes(program), _bytes(out_dir), ctypes.byref(o),
                                                           ctypes.byref(s)))
        return s

    def check_program(self, cell, program, as_written=False, capacity=64):
        """Reach and clearance checks of a program in its cell: (CheckSummary, [CheckViolation])."""
        o = CheckOptions()
        self._check(self.lib.accura_check_options_init(ctypes.byref(o), ctypes.sizeof(o)))
        o.as_written = 1 if as_written else 0
        s = CheckSummary()
        while True:
            v = (CheckViolation * capacity)()
            st = self.lib.accura_check_program(self.handle, _bytes(cell), _bytes(program), ctypes.byref(o),
                                               ctypes.byref(s), v, capacity)
            if st == ERROR_BUFFER_TOO_SMALL and s.n_violations > capacity:
                capacity = s.n_violations
                continue
            self._check(st)
            return s, list(v[:s.n_violations])
