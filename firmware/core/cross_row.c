#include "cross_row.h"

#include <math.h>
#include <string.h>

void xrow_init(xrow_state_t *s, double period_s)
{
    memset(s, 0, sizeof *s);
    /* Python's round(): half to even, rint in the default rounding mode */
    double steps = rint(XROW_DWELL_S / period_s);
    s->dwell_steps = steps < 1.0 ? 1 : (int)steps;
}

/* The median of v[0..n-1] (n >= 1; sorts v in place). */
static double median(double v[], int n)
{
    for (int i = 1; i < n; i++) { /* insertion sort: n <= XROW_MAX_ROWS */
        double x = v[i];
        int j = i - 1;
        while (j >= 0 && v[j] > x) {
            v[j + 1] = v[j];
            j--;
        }
        v[j + 1] = x;
    }
    int mid = n / 2;
    return n % 2 ? v[mid] : (v[mid - 1] + v[mid]) / 2.0;
}

void xrow_step(xrow_state_t *s, int n, const double flow_gps[], const bool passed[],
               bool excluded[])
{
    double sorted[XROW_MAX_ROWS];
    int k = 0;
    for (int i = 0; i < n && i < XROW_MAX_ROWS; i++) {
        excluded[i] = false;
        if (passed[i]) {
            sorted[k++] = flow_gps[i];
        } else {
            s->count[i] = 0;
            s->out[i] = false;
        }
    }
    if (k < XROW_MIN_ROWS) {
        memset(s->count, 0, sizeof s->count);
        memset(s->out, 0, sizeof s->out);
        return;
    }
    double med = median(sorted, k);
    double band = XROW_THRESHOLD_FRAC * med + XROW_FLOOR_GPS;
    for (int i = 0; i < n && i < XROW_MAX_ROWS; i++) {
        if (!passed[i]) {
            continue;
        }
        if (fabs(flow_gps[i] - med) > band) {
            s->count[i] = s->count[i] + 1 < s->dwell_steps ? s->count[i] + 1 : s->dwell_steps;
        } else {
            s->count[i] = s->count[i] > 0 ? s->count[i] - 1 : 0;
        }
        if (s->count[i] == s->dwell_steps) {
            s->out[i] = true;
        } else if (s->count[i] == 0) {
            s->out[i] = false;
        }
        excluded[i] = s->out[i];
    }
}

bool xrow_kept_mean(int n, const double flow_gps[], const bool passed[], const bool excluded[],
                    const bool fresh[], double *mean_gps, bool *any_fresh)
{
    double sum = 0.0;
    int kept = 0;
    bool new_report = false;
    for (int i = 0; i < n; i++) {
        if (passed[i] && !excluded[i]) {
            sum += flow_gps[i];
            kept++;
            new_report = new_report || fresh[i];
        }
    }
    *mean_gps = kept > 0 ? sum / (double)kept : 0.0;
    *any_fresh = new_report;
    return kept > 0;
}
