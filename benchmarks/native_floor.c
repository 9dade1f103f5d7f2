/* The C floor of benchmarks/bench_native.py: a fixed-step co-simulation loop in C over FMI 2.0
 * Co-Simulation instances that Python has instantiated and initialised (benchmarks/c_floor.py
 * compiles this file into a shared library and calls it through ctypes).
 *
 * Per step: fmi2DoStep on every instance, then the exchange, then the record of the row (the time,
 * every output and every input value): appended to a C array, or formatted as a CSV line
 * (cosim/kernel/csvrows.c, the bytes cosim's CSV sink writes, compiled in) into a 1 MiB buffer
 * written to a file descriptor whenever the next line might not fit, or not recorded at all.  The exchange is one batched fmi2GetReal and one
 * batched fmi2SetReal per instance, with the routing an index array (u[j] = y[source[j]]):
 *
 *   settle = 1  cosim's exchange (cosim/run/execution.py): read the outputs of the instances without
 *               direct feedthrough; then, in dependency order, route into each feedthrough
 *               instance, set its inputs and re-read its outputs; then route and set the inputs
 *               of the others.  A chain of feedthrough blocks settles within the instant.
 *   settle = 0  plain Jacobi (libcosim, fmpy.ssp, benchmarks/floor.py): read every output,
 *               then route and set every input; a feedthrough chain lags one step per block.
 *
 * Instances are given in the order the exchange visits them (dependency order).  Times are
 * cosim's grid (cosim/run/execution.py, Grid.time): t_k = start + k*h, computed, never accumulated,
 * and t_n = stop; each step is h_k = t_{k+1} - t_k.  The loop alone is timed, with
 * CLOCK_MONOTONIC.  Every FMI status above fmi2Warning stops the run and is reported.
 */
#include <stddef.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

size_t cosim_format_rows(const double *values, size_t rows, size_t columns, char *out);
int cosim_csv_value_max(void);

typedef int (*DoStep)(void *, double, double, int);
typedef int (*GetReal)(void *, const unsigned *, size_t, double *);
typedef int (*SetReal)(void *, const unsigned *, size_t, const double *);

typedef struct {
    int n;                    /* instances, in dependency order */
    void **component;         /* fmi2Component of each */
    DoStep *do_step;
    GetReal *get;
    SetReal *set;
    const unsigned *get_vr;   /* outputs of instance i: get_vr[get_off[i] .. get_off[i+1]) into y */
    const int *get_off;
    const unsigned *set_vr;   /* inputs of instance i: set_vr[set_off[i] .. set_off[i+1]) from u */
    const int *set_off;
    const int *source;        /* u[j] = y[source[j]] */
    const int *feedthrough;   /* 1: the instance's outputs depend on its inputs */
    double *y;
    double *u;
    int settle;
} Floor;

/* where a failed call happened: instance, step (-1 in the exchange before the loop), status */
typedef struct { int instance; long step; int status; } Failure;

static int get_outputs(const Floor *f, int i) {
    int n = f->get_off[i + 1] - f->get_off[i];
    return n ? f->get[i](f->component[i], f->get_vr + f->get_off[i], (size_t)n, f->y + f->get_off[i]) : 0;
}

static int set_inputs(const Floor *f, int i) {
    int first = f->set_off[i], n = f->set_off[i + 1] - first;
    for (int j = first; j < first + n; j++) f->u[j] = f->y[f->source[j]];
    return n ? f->set[i](f->component[i], f->set_vr + first, (size_t)n, f->u + first) : 0;
}

static int fail(Failure *failure, int i, long k, int status) {
    failure->instance = i;
    failure->step = k;
    failure->status = status;
    return 1;
}

/* The exchange at a communication point (see the file's comment); 0 on success. */
static int exchange(const Floor *f, long k, Failure *failure) {
    int s;
    for (int i = 0; i < f->n; i++)
        if (!(f->settle && f->feedthrough[i]) && (s = get_outputs(f, i)) > 1) return fail(failure, i, k, s);
    if (f->settle)
        for (int i = 0; i < f->n; i++)
            if (f->feedthrough[i]) {
                if ((s = set_inputs(f, i)) > 1) return fail(failure, i, k, s);
                if ((s = get_outputs(f, i)) > 1) return fail(failure, i, k, s);
            }
    for (int i = 0; i < f->n; i++)
        if (!(f->settle && f->feedthrough[i]) && (s = set_inputs(f, i)) > 1) return fail(failure, i, k, s);
    return 0;
}

int floor_exchange(const Floor *f, Failure *failure) { return exchange(f, -1, failure); }

static double grid(double start, double stop, double h, long n_steps, long k) {
    return k >= n_steps ? stop : start + (double)k * h;
}

/* Write all n bytes of text to fd; 0 on success. */
static int write_all(int fd, const char *text, size_t n) {
    while (n) {
        ssize_t done = write(fd, text, n);
        if (done <= 0) return 1;
        text += done;
        n -= (size_t)done;
    }
    return 0;
}

enum { CSV_BUFFER = 1 << 20 };

/* n_steps steps of h from start to stop, each step's row (t_{k+1}, the outputs, the inputs) recorded:
 * into ``record`` (n_steps rows of 1 + ny + nu doubles) when it is not NULL, as CSV lines written to
 * ``csv_fd`` when it is not negative, else nowhere; *seconds: the loop's wall time.  0 on success
 * (a failed write: status -1 of instance -1). */
int floor_run(const Floor *f, double start, double stop, double h, long n_steps, double *record, int csv_fd,
              double *seconds, Failure *failure) {
    size_t ny = (size_t)f->get_off[f->n], nu = (size_t)f->set_off[f->n], width = 1 + ny + nu;
    struct timespec t0, t1;
    int failed = 0;
    double row[width];
    static char text[CSV_BUFFER];
    size_t used = 0, line_max = width * (size_t)cosim_csv_value_max();
    clock_gettime(CLOCK_MONOTONIC, &t0);
    for (long k = 0; k < n_steps && !failed; k++) {
        double t = grid(start, stop, h, n_steps, k), t_next = grid(start, stop, h, n_steps, k + 1), step = t_next - t;
        for (int i = 0; i < f->n; i++) {
            int s = f->do_step[i](f->component[i], t, step, 1);
            if (s > 1) { failed = fail(failure, i, k, s); break; }
        }
        if (failed || (failed = exchange(f, k, failure))) break;
        if (record != NULL) {
            record[0] = t_next;
            memcpy(record + 1, f->y, ny * sizeof(double));
            memcpy(record + 1 + ny, f->u, nu * sizeof(double));
            record += width;
        } else if (csv_fd >= 0) {
            if (used + line_max > sizeof text) {
                if (write_all(csv_fd, text, used)) { failed = fail(failure, -1, k, -1); break; }
                used = 0;
            }
            row[0] = t_next;
            memcpy(row + 1, f->y, ny * sizeof(double));
            memcpy(row + 1 + ny, f->u, nu * sizeof(double));
            used += cosim_format_rows(row, 1, width, text + used);
        }
    }
    if (!failed && used && write_all(csv_fd, text, used)) failed = fail(failure, -1, n_steps, -1);
    clock_gettime(CLOCK_MONOTONIC, &t1);
    *seconds = (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
    return failed;
}
