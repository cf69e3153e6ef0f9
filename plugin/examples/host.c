/*
 * A minimal CAD / OLP host: loads libaccura_plugin.so by path with dlopen, resolves the C API
 * with dlsym, compensates poses and a seam (LIN, CIRC, LIN), and checks the numbers. Run by
 * ctest (plugin_c_host); exit status 0 when every check holds.
 *
 *   accura_plugin_host LIB.so CALIBRATED_MODEL.xml NOMINAL_ROBOT.xml
 *
 * The calibrated model is a KR 16 with a welding torch (tests/data/plugin/kr16_calibrated.xml);
 * the nominal robot is the same robot without deviations (robots/kuka_kr16.xml).
 */
#include <dlfcn.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "accura_plugin.h"

/* The API as function pointers, resolved from the library. */
typedef struct api {
  accura_status (*version)(int*, int*, int*, int*);
  accura_status (*status_name)(accura_status, const char**);
  accura_status (*last_error)(const accura_model*, const char**);
  accura_status (*model_create)(accura_model**);
  accura_status (*model_free)(accura_model*);
  accura_status (*load_options_init)(accura_load_options*, size_t);
  accura_status (*model_load)(accura_model*, const char*, const accura_load_options*);
  accura_status (*forward_kinematics)(accura_model*, accura_which_model, const double*, size_t, accura_pose*);
  accura_status (*compensate_pose)(accura_model*, const accura_pose*, const accura_configuration*, accura_pose_result*);
  accura_status (*compensate_poses)(accura_model*, const accura_pose*, const accura_configuration*, size_t, int,
                                    accura_pose_result*, size_t*);
  accura_status (*compensate_path)(accura_model*, const accura_pose*, const accura_configuration*, const accura_path_motion*,
                                   size_t, double, accura_path_point*, size_t, accura_path_result*, accura_motion_report*);
} api;

static int failures = 0;

#define CHECK(cond, ...)                                   \
  do {                                                     \
    if (!(cond)) {                                         \
      ++failures;                                          \
      fprintf(stderr, "FAILED %s:%d: %s: ", __FILE__, __LINE__, #cond); \
      fprintf(stderr, __VA_ARGS__);                        \
      fprintf(stderr, "\n");                               \
    }                                                      \
  } while (0)

static void* resolve(void* lib, const char* name) {
  void* p = dlsym(lib, name);
  if (!p) {
    fprintf(stderr, "host: %s not found in the library: %s\n", name, dlerror());
    exit(2);
  }
  return p;
}

static accura_pose pose(double x, double y, double z, double a, double b, double c) {
  accura_pose p;
  p.x_mm = x;
  p.y_mm = y;
  p.z_mm = z;
  p.a_deg = a;
  p.b_deg = b;
  p.c_deg = c;
  return p;
}

static double dist_mm(const accura_pose* p, const accura_pose* q) {
  const double dx = p->x_mm - q->x_mm, dy = p->y_mm - q->y_mm, dz = p->z_mm - q->z_mm;
  return sqrt(dx * dx + dy * dy + dz * dz);
}

/* R = Rz(A) Ry(B) Rx(C) of a pose. */
static void rotation(const accura_pose* p, double R[3][3]) {
  const double d = 3.14159265358979323846 / 180;
  const double ca = cos(p->a_deg * d), sa = sin(p->a_deg * d), cb = cos(p->b_deg * d), sb = sin(p->b_deg * d);
  const double cc = cos(p->c_deg * d), sc = sin(p->c_deg * d);
  R[0][0] = ca * cb;
  R[0][1] = ca * sb * sc - sa * cc;
  R[0][2] = ca * sb * cc + sa * sc;
  R[1][0] = sa * cb;
  R[1][1] = sa * sb * sc + ca * cc;
  R[1][2] = sa * sb * cc - ca * sc;
  R[2][0] = -sb;
  R[2][1] = cb * sc;
  R[2][2] = cb * cc;
}

/* Rotation between two poses (deg; from the largest matrix difference, exact to first order:
 * any A, B, C representation of the same rotation gives 0). */
static double angle_diff_deg(const accura_pose* p, const accura_pose* q) {
  double R[3][3], S[3][3], m = 0;
  int i, j;
  rotation(p, R);
  rotation(q, S);
  for (i = 0; i < 3; ++i)
    for (j = 0; j < 3; ++j)
      if (fabs(R[i][j] - S[i][j]) > m) m = fabs(R[i][j] - S[i][j]);
  return m * 180 / 3.14159265358979323846;
}

static const char* message(const api* a, const accura_model* m) {
  const char* msg = "";
  a->last_error(m, &msg);
  return msg;
}

int main(int argc, char** argv) {
  api a;
  void* lib;
  accura_model* model = NULL;
  accura_load_options options;
  int major = -1, minor = -1, patch = -1, abi = -1;
  size_t i;
  if (argc != 4) {
    fprintf(stderr, "usage: %s LIB.so CALIBRATED_MODEL.xml NOMINAL_ROBOT.xml\n", argv[0]);
    return 2;
  }
  lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
  if (!lib) {
    fprintf(stderr, "host: cannot load %s: %s\n", argv[1], dlerror());
    return 2;
  }
  /* dlsym returns void*; POSIX guarantees it converts to a function pointer */
  *(void**)&a.version = resolve(lib, "accura_version");
  *(void**)&a.status_name = resolve(lib, "accura_status_name");
  *(void**)&a.last_error = resolve(lib, "accura_last_error");
  *(void**)&a.model_create = resolve(lib, "accura_model_create");
  *(void**)&a.model_free = resolve(lib, "accura_model_free");
  *(void**)&a.load_options_init = resolve(lib, "accura_load_options_init");
  *(void**)&a.model_load = resolve(lib, "accura_model_load");
  *(void**)&a.forward_kinematics = resolve(lib, "accura_forward_kinematics");
  *(void**)&a.compensate_pose = resolve(lib, "accura_compensate_pose");
  *(void**)&a.compensate_poses = resolve(lib, "accura_compensate_poses");
  *(void**)&a.compensate_path = resolve(lib, "accura_compensate_path");

  /* 1. version: the library speaks this header's ABI */
  CHECK(a.version(&major, &minor, &patch, &abi) == ACCURA_OK, "accura_version");
  printf("library %d.%d.%d, ABI %d\n", major, minor, patch, abi);
  CHECK(abi == ACCURA_PLUGIN_ABI_VERSION, "ABI %d, header %d", abi, ACCURA_PLUGIN_ABI_VERSION);
  CHECK(a.model_create(&model) == ACCURA_OK && model != NULL, "create");

  /* 2. bad input gives statuses and messages, never a crash */
  {
    accura_pose_result r;
    accura_pose t = pose(1000, 0, 500, 0, 180, 0);
    const char* missing = "/nonexistent/dir/model_that_is_not_there.xml";
    CHECK(a.compensate_pose(model, &t, NULL, &r) == ACCURA_ERROR_INVALID_ARGUMENT, "compensation before a model is loaded");
    CHECK(a.model_load(model, missing, NULL) == ACCURA_ERROR_INPUT, "missing file");
    CHECK(strstr(message(&a, model), missing) != NULL, "the message names the path: '%s'", message(&a, model));
    printf("missing file: %s\n", message(&a, model));
    CHECK(a.model_load(NULL, argv[2], NULL) == ACCURA_ERROR_NULL_ARGUMENT, "NULL handle");
    CHECK(a.model_load(model, NULL, NULL) == ACCURA_ERROR_NULL_ARGUMENT, "NULL path");
    CHECK(a.load_options_init(&options, sizeof(options) - 1) == ACCURA_ERROR_INVALID_ARGUMENT, "wrong struct size");
    CHECK(a.load_options_init(&options, sizeof(options)) == ACCURA_OK, "options");
    options.struct_size = 8;
    CHECK(a.model_load(model, argv[2], &options) == ACCURA_ERROR_INVALID_ARGUMENT, "struct_size 8");
  }

  /* 3. the nominal robot: nominal = real, so the command is the target itself */
  {
    accura_pose_result r;
    accura_pose t = pose(1100, -250, 500, 0, 180, 0);
    CHECK(a.model_load(model, argv[3], NULL) == ACCURA_OK, "load %s: %s", argv[3], message(&a, model));
    CHECK(a.compensate_pose(model, &t, NULL, &r) == ACCURA_OK, "%s", message(&a, model));
    CHECK(dist_mm(&r.command, &t) < 1e-6 && angle_diff_deg(&r.command, &t) < 1e-6, "nominal robot: command moved by %.3g mm",
          dist_mm(&r.command, &t));
  }

  /* 4. the calibrated KR 16: FK_real(q') = target, FK_controller(q') = command */
  {
    accura_pose targets[4];
    accura_configuration configs[4];
    accura_pose_result results[4], single;
    size_t n_ok = 0;
    targets[0] = pose(1100, -250, 500, 0, 180, 0);
    targets[1] = pose(1260, -50, 500, 0, 180, 0);
    targets[2] = pose(900, 400, 900, 40, 120, -20);
    targets[3] = pose(1250, 300, 1150, 0, 110, 30);
    for (i = 0; i < 4; ++i) {
      configs[i].status = 2; /* KUKA's usual basic configuration; T any */
      configs[i].turn = -1;
    }
    CHECK(a.model_load(model, argv[2], NULL) == ACCURA_OK, "load %s: %s", argv[2], message(&a, model));
    CHECK(a.compensate_poses(model, targets, configs, 4, 0, results, &n_ok) == ACCURA_OK, "%s", message(&a, model));
    CHECK(n_ok == 4, "n_ok %lu", (unsigned long)n_ok);
    for (i = 0; i < 4; ++i) {
      accura_pose real, ctrl;
      CHECK(results[i].status == ACCURA_OK, "pose %lu", (unsigned long)i);
      CHECK(results[i].dof == 6, "dof %d", results[i].dof);
      CHECK(a.forward_kinematics(model, ACCURA_REAL, results[i].q_real, 6, &real) == ACCURA_OK, "fk");
      CHECK(a.forward_kinematics(model, ACCURA_CONTROLLER, results[i].q_real, 6, &ctrl) == ACCURA_OK, "fk");
      CHECK(dist_mm(&real, &targets[i]) < 1e-6 && angle_diff_deg(&real, &targets[i]) < 1e-6,
            "the real robot at q' misses the target by %.3g mm", dist_mm(&real, &targets[i]));
      CHECK(dist_mm(&ctrl, &results[i].command) < 1e-6 && angle_diff_deg(&ctrl, &results[i].command) < 1e-6,
            "the controller at q' is %.3g mm from the command", dist_mm(&ctrl, &results[i].command));
      CHECK(fabs(results[i].correction_mm - dist_mm(&results[i].command, &targets[i])) < 1e-9, "correction_mm");
      /* the KR 16's errors (0.3 mm lengths, 0.03 deg angles, 1 sigma) move a point by about 1-3 mm */
      CHECK(results[i].correction_mm > 0.2 && results[i].correction_mm < 8, "correction %.4f mm", results[i].correction_mm);
      CHECK(results[i].configuration.status == 2, "S %d", results[i].configuration.status);
      CHECK(a.compensate_pose(model, &targets[i], &configs[i], &single) == ACCURA_OK, "%s", message(&a, model));
      CHECK(memcmp(&single.command, &results[i].command, sizeof(accura_pose)) == 0, "single and list calls give the same bytes");
      printf("pose %lu: correction %.4f mm %.5f deg, command {X %.4f, Y %.4f, Z %.4f, A %.5f, B %.5f, C %.5f} S %d T %d\n",
             (unsigned long)i, results[i].correction_mm, results[i].correction_deg, results[i].command.x_mm, results[i].command.y_mm,
             results[i].command.z_mm, results[i].command.a_deg, results[i].command.b_deg, results[i].command.c_deg,
             results[i].configuration.status, results[i].configuration.turn);
    }
    {
      accura_pose far = pose(5000, 0, 500, 0, 180, 0);
      const char* name = "";
      CHECK(a.compensate_pose(model, &far, NULL, &single) == ACCURA_ERROR_UNREACHABLE, "5 m away");
      CHECK(single.status == ACCURA_ERROR_UNREACHABLE, "per-pose status");
      a.status_name(single.status, &name);
      printf("5 m away: %s: %s\n", name, message(&a, model));
      CHECK(a.compensate_pose(model, NULL, NULL, &single) == ACCURA_ERROR_NULL_ARGUMENT, "NULL target");
    }
  }

  /* 5. a seam: LIN 200 mm, a half circle of radius 80 mm, LIN 200 mm back, tol 0.05 mm */
  {
    const double tol_mm = 0.05;
    accura_pose start = pose(1100, -250, 500, 0, 180, 0);
    accura_path_motion motions[3];
    accura_path_result res;
    accura_motion_report reports[3];
    accura_path_point* points;
    accura_status st;
    memset(motions, 0, sizeof(motions));
    motions[0].type = ACCURA_LIN;
    motions[0].end = pose(1100, -50, 500, 0, 180, 0);
    motions[1].type = ACCURA_CIRC;
    motions[1].aux = pose(1180, 30, 500, 0, 180, 0);
    motions[1].end = pose(1260, -50, 500, 0, 180, 0);
    motions[2].type = ACCURA_LIN;
    motions[2].end = pose(1260, -250, 500, 0, 180, 0);
    st = a.compensate_path(model, &start, NULL, motions, 3, tol_mm, NULL, 0, &res, reports);
    CHECK(st == ACCURA_ERROR_BUFFER_TOO_SMALL, "capacity 0 -> buffer too small, got %d", (int)st);
    CHECK(res.n_points >= 3, "n_points %lu", (unsigned long)res.n_points);
    points = (accura_path_point*)calloc(res.n_points, sizeof(accura_path_point));
    if (!points) return 2;
    st = a.compensate_path(model, &start, NULL, motions, 3, tol_mm, points, res.n_points, &res, reports);
    CHECK(st == ACCURA_OK, "%s", message(&a, model));
    printf("seam: %lu points (%d added); path error %.4f mm as programmed, %.4f mm end points compensated, %.4f mm with the points "
           "(bound %.4f mm)\n",
           (unsigned long)res.n_points, res.points_added, res.max_error_uncompensated_mm, res.max_error_before_mm,
           res.max_error_after_mm, res.max_error_bound_mm);
    CHECK(res.max_error_after_mm <= tol_mm, "after %.4f", res.max_error_after_mm);
    CHECK(res.max_error_bound_mm <= tol_mm, "bound %.4f", res.max_error_bound_mm);
    CHECK(res.max_error_uncompensated_mm > 0.5, "the uncompensated seam is off by about a millimetre: %.4f",
          res.max_error_uncompensated_mm);
    CHECK(res.max_error_before_mm > res.max_error_after_mm, "points help");
    CHECK((int)res.n_points == 3 + res.points_added, "n_points = motions + added");
    CHECK(res.failed_motion == -1, "failed_motion %d", res.failed_motion);
    for (i = 0; i < res.n_points; ++i) {
      CHECK(i == 0 || points[i].motion >= points[i - 1].motion, "motions in order");
      CHECK(points[i].type == motions[points[i].motion].type, "type kept");
      if (!points[i].inserted) /* an end point: its command is within a few mm of the target */
        CHECK(dist_mm(&points[i].end, &motions[points[i].motion].end) < 8, "end point %lu", (unsigned long)i);
    }
    for (i = 0; i < 3; ++i) CHECK(reports[i].max_error_after_mm <= tol_mm, "motion %lu", (unsigned long)i);
    CHECK(fabs(reports[0].length_mm - 200) < 1e-6 && fabs(reports[1].length_mm - 80 * 3.14159265358979) < 1e-3,
          "lengths %.6f %.6f", reports[0].length_mm, reports[1].length_mm);
    {
      st = a.compensate_path(model, &start, NULL, motions, 3, -1, points, res.n_points, &res, NULL);
      CHECK(st == ACCURA_ERROR_INVALID_ARGUMENT, "negative tolerance");
      motions[1].aux = pose(1180, -50, 500, 0, 180, 0); /* on the line: no circle */
      st = a.compensate_path(model, &start, NULL, motions, 3, tol_mm, points, res.n_points, &res, NULL);
      CHECK(st == ACCURA_ERROR_NUMERICAL, "collinear CIRC: %d %s", (int)st, message(&a, model));
    }
    free(points);
  }

  CHECK(a.model_free(model) == ACCURA_OK, "free");
  CHECK(a.model_free(NULL) == ACCURA_OK, "free NULL");
  dlclose(lib);
  if (failures) {
    fprintf(stderr, "host: %d check(s) failed\n", failures);
    return 1;
  }
  printf("host: all checks passed\n");
  return 0;
}
