/* Time one control step of each core (worst case: an update on every step). Prints us/step;
 * as a ctest it only checks that the cores are far inside their control periods. */
#include <stdio.h>
#include <time.h>

#include "fuzzy_pid.h"
#include "piecewise_pid.h"

#define STEPS 200000

static volatile double sink;

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

static double bench_ppid(ppid_law_t law)
{
    ppid_params_t p;
    ppid_defaults(&p, law);
    ppid_state_t s;
    ppid_reset(&s);
    double t0 = now_s();
    for (int i = 0; i < STEPS; i++) {
        double measured = 23.0 + (double)(i % 17) * 0.3 - 2.4;
        ppid_output_t o = ppid_step(&p, &s, 23.0 + (double)(i % 3), measured, true, true);
        sink = o.volts;
    }
    return (now_s() - t0) / STEPS * 1e6;
}

static double bench_fpid(void)
{
    fpid_params_t p;
    fpid_defaults(&p);
    fpid_state_t s;
    fpid_reset(&s);
    double t0 = now_s();
    for (int i = 0; i < STEPS; i++) {
        double depth = 30.0 + (double)(i % 101) * 2.0 - 100.0; /* E and EC sweep the sets */
        fpid_output_t o = fpid_step(&p, &s, 30.0, depth, true, true);
        sink = o.speed_mm_s;
    }
    return (now_s() - t0) / STEPS * 1e6;
}

int main(void)
{
    double phys = bench_ppid(PPID_LAW_PHYSICAL);
    double paper = bench_ppid(PPID_LAW_PAPER_LITERAL);
    double open = bench_ppid(PPID_LAW_OPEN_LOOP);
    double fuzzy = bench_fpid();
    printf("us per control step (%d steps each, an update every step):\n", STEPS);
    printf("  piecewise PID, physical       %8.4f us  (period 100 ms)\n", phys);
    printf("  piecewise PID, paper-literal  %8.4f us  (period 100 ms)\n", paper);
    printf("  piecewise PID, open loop      %8.4f us  (period 100 ms)\n", open);
    printf("  fuzzy self-tuning PID         %8.4f us  (period 10 ms)\n", fuzzy);
    /* generous bound: only catches a pathological slowdown, not machine noise */
    return phys < 100.0 && paper < 100.0 && open < 100.0 && fuzzy < 500.0 ? 0 : 1;
}
