/* The probe's model (lsbus_probe/model.c) with PROBE_TIMED (config.h). */
#include "../lsbus_probe/model.c"
