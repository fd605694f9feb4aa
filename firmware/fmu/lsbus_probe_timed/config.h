/* agrihil-lsbus-probe-timed: the probe with a time-based Tx_Clock (every 0.3 s). */
#define PROBE_TIMED
#define MODEL_IDENTIFIER agrihil_lsbus_probe_timed
#define INSTANTIATION_TOKEN "{0b1f5c1a-agri-hil0-lsbus-probe000002}"
#include "../lsbus_probe/config.h"
