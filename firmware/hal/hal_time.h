/* Time abstraction: a monotonic clock and an absolute-deadline sleep.
 * To port to an MCU: a free-running timer (or the RTOS tick) for hal_time_now_ns and a
 * wait-until on it for hal_time_sleep_until. */
#ifndef AGRIHIL_HAL_TIME_H
#define AGRIHIL_HAL_TIME_H

#include <stdint.h>

/* Monotonic time in nanoseconds (arbitrary origin). */
int64_t hal_time_now_ns(void);

/* Sleep until the monotonic time reaches deadline_ns. Returns early (0) when a signal
 * interrupts the sleep; the caller checks its flags and calls again. */
int hal_time_sleep_until(int64_t deadline_ns);

#endif
