/* Compiled as strict C89 (-std=c90 -pedantic-errors): accura_plugin.h is usable from C89. */
#include "accura_plugin.h"

int accura_plugin_header_is_c89(void);
int accura_plugin_header_is_c89(void) {
  accura_pose p;
  accura_path_motion m;
  accura_pose_result r;
  p.x_mm = 0;
  m.type = ACCURA_LIN;
  r.status = ACCURA_OK;
  return (int)(p.x_mm + m.type + r.status) + (int)sizeof(accura_load_options) * 0 + ACCURA_PLUGIN_ABI_VERSION;
}
