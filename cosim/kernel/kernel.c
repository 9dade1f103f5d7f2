/* The master's stepping loop in C (cosim.kernel): one communication step's program of operations
 * (cosim.run.program), run from step k to step k_end, one recorded row after each step.
 *
 * cosim.run.program compiles the step -- the doSteps (Jacobi, or Gauss-Seidel with each component's
 * inputs routed and set before and its outputs read after its doStep), the batched gets, the
 * direct-feedthrough settling in dependency order, the routes (y * factor + offset, two
 * roundings: built with -ffp-contract=off; or a value looked up in a mapping table), the sets --
 * into one array of operations, which
 * cosim.run.interpreters runs either in Python or here: this file only runs it, so the calls, their
 * order and the arithmetic are the same in both.  An operation this file cannot run (OP_PYTHON:
 * a call Python makes, a String route, a transformation without a C form, an input table, an
 * algebraic loop's iteration) is handed back to Python, which runs it and resumes here after it.
 *
 * The loop returns to Python (cosim_run's result, bits of KERNEL_*) when:
 *   - step k_end is reached (Python's progress stride);
 *   - the recorder's buffer is full, or its flush deadline (CLOCK_MONOTONIC, as Python's
 *     time.monotonic) has passed: Python hands the rows to the sinks;
 *   - the stop flag is set (a signal: cosim_watch_signals), checked after each recorded row;
 *   - an FMI call returned a status other than OK and Warning, or a doStep's post-step flag
 *     (fmi3DoStep's terminateSimulation) is set: Python handles the status;
 *   - a route's value could not be made (KERNEL_UNMADE, the route's index in ``status``): its
 *     factor and offset turned a finite value into an infinite one, or its table names no target
 *     for the value; Python makes the operation again and reports it as the Python interpreter does;
 *   - the next operation is OP_PYTHON (KERNEL_YIELD).
 * In the last three cases, and for a status Python decides to go on after, Python calls again
 * with ``first``: the operation of step k to resume at.
 * No Python C API: loaded with ctypes, which releases the GIL for the call (pythonfmu FMUs
 * take it themselves in each FMI call). */
#define _XOPEN_SOURCE 700
#include <pthread.h>
#include <signal.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

enum { OP_STEP = 0, OP_GET = 1, OP_SET = 2, OP_ROUTE = 3, OP_PYTHON = 4, OP_MAP = 5 };
enum { KERNEL_END = 1, KERNEL_FULL = 2, KERNEL_FLUSH = 4, KERNEL_STOP = 8, KERNEL_STATUS = 16,
       KERNEL_UNMADE = 32, KERNEL_YIELD = 64 };

typedef int (*fmi2DoStep)(void *, double, double, int);
typedef int (*fmi3DoStep)(void *, double, double, bool, bool *, bool *, bool *, double *);
typedef int (*fmi2Exchange)(void *, const unsigned int *, size_t, void *);
typedef int (*fmi3Exchange)(void *, const unsigned int *, size_t, void *, size_t);

/* One operation of a step.  OP_STEP/OP_GET/OP_SET: an FMI call (api 2 or 3: the C signature) on
 * ``instance``; fmi3DoStep's out-arguments are ``event``, ``terminate``, ``early``, ``last`` (the
 * instance's own, which its post-step reads in Python), and a doStep after which ``terminate``
 * (when not NULL) is true returns to Python whatever its status.
 * OP_ROUTE: U[dst[j]] = Y[src[j]] (identity) or Y[src[j]] * factor[j] + offset[j], on doubles
 * or (integer) on C ints, as fmi2Integer and fmi2Boolean are.  OP_MAP: U[dst[j]] = the value
 * tables[j] maps Y[src[j]] to (C ints; ``tables`` shares its place with ``factor``).  ``thread``: with a pool, which thread makes a doStep of
 * the parallel phase (0: the calling thread). */
/* A mapping table (cosim.model.transforms.Table): ``n`` keys in ascending order and their values;
 * ``boolean``: a key is looked up as 0 or 1 (any value but 0 as 1). */
typedef struct {
    const int *keys, *values;
    size_t n;
    int boolean;
} Table;

typedef struct {
    int kind, api, integer, identity, thread;
    void *fn, *instance;
    const unsigned int *vr;
    size_t n;
    void *values;
    bool *event, *terminate, *early;
    double *last;
    const intptr_t *src, *dst;
    union { /* OP_ROUTE's factors, or OP_MAP's tables: Op keeps the size it had before tables */
        const double *factor;
        const Table *tables;
    };
    const double *offset;
    void *Y, *U;
} Op;

/* One exchange buffer copied into every row: n doubles or (integer) C ints, value j into the
 * row's column columns[j] (the result's column order, cosim.record.observers.Recorder);
 * ``consecutive``: columns[j] = columns[0] + j (doubles then copied with one memcpy). */
typedef struct {
    void *values;
    size_t n;
    int integer;
    int consecutive;
    const int *columns;
} Source;

struct Pool;

/* ``pool`` (cosim_pool_new), when not NULL: the first ``n_parallel`` operations are doSteps
 * made concurrently, each by its ``thread``, their statuses in ``statuses`` (Jacobi: the
 * components step from the inputs of the last communication point, independently). */
typedef struct {
    const Op *ops;
    int n_ops;
    struct Pool *pool;
    int n_parallel;
    int *statuses;
    const Source *sources;
    int n_sources;
    int columns;
    double start, step, stop;
    long long steps;
} Program;

/* What one call does: steps k .. k_end - 1 (k advances past every completed step; step k
 * begins at operation ``first``, the others at 0), rows into ``rows`` (row-major, ``columns``
 * doubles each: the time, then each source's values in their columns; a column no source names,
 * a root output's, is left to Python) up to ``free_rows``; ``samples`` counts every row of the run and is stored into
 * ``count`` after each row (the journal's row counter).  On KERNEL_STATUS, KERNEL_UNMADE and
 * KERNEL_YIELD: ``op`` (and ``status``) of the operation, in step k (not completed). */
typedef struct {
    long long k, k_end;
    double *rows;
    long long free_rows, rows_done;
    int64_t *count;
    long long samples;
    double flush_at;
    volatile int *stop;
    int first, op, status;
} Run;

/* The layout the ctypes mirrors of cosim/kernel/__init__.py declare: bump KERNEL_ABI_VERSION
 * with any change to Op, Source, Program or Run (their sizes are checked too, so a stale
 * library built before an edit is refused rather than read out of step). */
#ifndef KERNEL_ABI_VERSION
#define KERNEL_ABI_VERSION 5
#endif
enum { KERNEL_ABI_STRUCTS = 5 };

/* The ABI version; ``sizes`` (KERNEL_ABI_STRUCTS of them) receives sizeof Op, Source, Program,
 * Run and Table, in that order. */
int cosim_kernel_abi(size_t *sizes) {
    sizes[0] = sizeof(Op);
    sizes[1] = sizeof(Source);
    sizes[2] = sizeof(Program);
    sizes[3] = sizeof(Run);
    sizes[4] = sizeof(Table);
    return KERNEL_ABI_VERSION;
}

static double grid_time(const Program *p, long long k) {
    return k >= p->steps ? p->stop : p->start + (double)k * p->step;
}

static double seconds(clockid_t clock) {
    struct timespec ts;
    clock_gettime(clock, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

/* How far the coarse clock may lag CLOCK_MONOTONIC (it is updated at the scheduler's tick, a few
 * ms; never ahead of it). */
#define COARSE_LAG 0.05

/* Whether CLOCK_MONOTONIC (Python's time.monotonic) has passed ``deadline``, asked at every row:
 * where there is a coarse form of the clock (a few ns a read rather than ~20), the precise clock
 * is read only within COARSE_LAG of the deadline. */
static int passed(double deadline) {
#ifdef CLOCK_MONOTONIC_COARSE
    if (seconds(CLOCK_MONOTONIC_COARSE) + COARSE_LAG < deadline) return 0;
#endif
    return seconds(CLOCK_MONOTONIC) > deadline;
}

/* Route; -1, or the index of the first route whose factor and offset made a finite value
 * infinite (the values up to it routed). */
static long route(const Op *o) {
    size_t n = o->n;
    if (o->integer) {
        const int *Y = o->Y;
        int *U = o->U;
        if (o->identity)
            for (size_t j = 0; j < n; j++) U[o->dst[j]] = Y[o->src[j]];
        else
            for (size_t j = 0; j < n; j++) U[o->dst[j]] = (int)((double)Y[o->src[j]] * o->factor[j] + o->offset[j]);
    } else {
        const double *Y = o->Y;
        double *U = o->U;
        if (o->identity)
            for (size_t j = 0; j < n; j++) U[o->dst[j]] = Y[o->src[j]];
        else
            for (size_t j = 0; j < n; j++) {
                double y = Y[o->src[j]], u = y * o->factor[j] + o->offset[j];
                if (!isfinite(u) && isfinite(y)) return (long)j;
                U[o->dst[j]] = u;
            }
    }
    return -1;
}

/* Mapped routes; -1, or the index of the first route whose table names no target for its value
 * (the values up to it routed). */
static long map_values(const Op *o) {
    const int *Y = o->Y;
    int *U = o->U;
    for (size_t j = 0; j < o->n; j++) {
        const Table *table = &o->tables[j];
        int key = Y[o->src[j]];
        if (table->boolean) key = key != 0;
        size_t lo = 0, hi = table->n;
        while (lo < hi) {
            size_t mid = lo + (hi - lo) / 2;
            if (table->keys[mid] < key) lo = mid + 1;
            else hi = mid;
        }
        if (lo == table->n || table->keys[lo] != key) return (long)j;
        U[o->dst[j]] = table->values[lo];
    }
    return -1;
}

/* The status of one operation (for a route: -1, or the index of the route whose value could not
 * be made). */
static int operate(const Op *o, double t, double h) {
    switch (o->kind) {
    case OP_STEP:
        if (o->api == 2)
            return ((fmi2DoStep)o->fn)(o->instance, t, h, 1);
        return ((fmi3DoStep)o->fn)(o->instance, t, h, true, o->event, o->terminate, o->early, o->last);
    case OP_GET:
    case OP_SET:
        if (o->api == 2)
            return ((fmi2Exchange)o->fn)(o->instance, o->vr, o->n, o->values);
        return ((fmi3Exchange)o->fn)(o->instance, o->vr, o->n, o->values, o->n);
    default: /* the switch of the doSteps, gets and sets as before OP_MAP: a route is the rarer case */
        return (int)(o->kind == OP_MAP ? map_values(o) : route(o));
    }
}

/* Whether the loop stops at operation o after status s: a doStep goes on after OK and Warning
 * unless its post-step flag is set (fmi3DoStep asks to terminate); a get or set after any status
 * up to Warning; a route when one of its values could not be made. */
static int stops(const Op *o, int s) {
    if (o->kind == OP_ROUTE || o->kind == OP_MAP) return s >= 0;
    return o->kind == OP_STEP ? (s != 0 && s != 1) || (o->terminate != NULL && *o->terminate) : s > 1;
}

static void parallel_steps(const Program *p, double t, double h);

int cosim_run(const Program *p, Run *r) {
    int reason = 0, first = r->first;
    while (r->k < r->k_end) {
        double t = grid_time(p, r->k), t_next = grid_time(p, r->k + 1), h = t_next - t;
        int i = first;
        first = 0;
        if (p->pool != NULL && i < p->n_parallel) {
            if (i == 0) parallel_steps(p, t, h);
            for (; i < p->n_parallel; i++) /* resumed: the statuses of this step's parallel doSteps */
                if (stops(&p->ops[i], p->statuses[i])) {
                    r->op = i;
                    r->status = p->statuses[i];
                    return KERNEL_STATUS;
                }
        }
        for (; i < p->n_ops; i++) {
            const Op *o = &p->ops[i];
            if (o->kind == OP_PYTHON) {
                r->op = i;
                return KERNEL_YIELD;
            }
            int s = operate(o, t, h);
            if (stops(o, s)) {
                r->op = i;
                r->status = s;
                return o->kind == OP_ROUTE || o->kind == OP_MAP ? KERNEL_UNMADE : KERNEL_STATUS;
            }
        }
        double *row = r->rows + r->rows_done * p->columns;
        row[0] = t_next;
        for (int i = 0; i < p->n_sources; i++) {
            const Source *src = &p->sources[i];
            const int *columns = src->columns;
            if (src->integer)
                for (size_t j = 0; j < src->n; j++) row[columns[j]] = (double)((const int *)src->values)[j];
            else if (src->consecutive)
                memcpy(row + columns[0], src->values, src->n * sizeof(double));
            else
                for (size_t j = 0; j < src->n; j++) row[columns[j]] = ((const double *)src->values)[j];
        }
        r->rows_done++;
        r->samples++;
        *r->count = r->samples;
        r->k++;
        if (r->rows_done == r->free_rows) reason |= KERNEL_FULL;
        if (passed(r->flush_at)) reason |= KERNEL_FLUSH;
        if (*r->stop) reason |= KERNEL_STOP;
        if (reason) return reason;
    }
    return KERNEL_END;
}

/* Signals during a run: SIGINT, SIGTERM and SIGALRM set ``flag`` (to the signal's number) and
 * then go to the handler they had (Python's, which records them in the cosim.run.interrupts
 * StopRequest once the kernel returns), so the loop sees them at the next row. */
static const int WATCHED[3] = {SIGINT, SIGTERM, SIGALRM};
static struct sigaction previous[3];
static volatile int *watch_flag;
static int watching;

static void on_signal(int signum, siginfo_t *info, void *context) {
    if (watch_flag != NULL && *watch_flag == 0) *watch_flag = signum;
    for (int i = 0; i < 3; i++) {
        if (WATCHED[i] != signum) continue;
        if (previous[i].sa_flags & SA_SIGINFO)
            previous[i].sa_sigaction(signum, info, context);
        else if (previous[i].sa_handler != SIG_DFL && previous[i].sa_handler != SIG_IGN)
            previous[i].sa_handler(signum);
    }
}

int cosim_watch_signals(volatile int *flag) {
    if (watching) return -1;
    struct sigaction action;
    memset(&action, 0, sizeof action);
    action.sa_sigaction = on_signal;
    action.sa_flags = SA_SIGINFO | SA_ONSTACK;
    sigemptyset(&action.sa_mask);
    watch_flag = flag;
    for (int i = 0; i < 3; i++)
        if (sigaction(WATCHED[i], &action, &previous[i]) != 0) {
            while (i-- > 0) sigaction(WATCHED[i], &previous[i], NULL);
            watch_flag = NULL;
            return -1;
        }
    watching = 1;
    return 0;
}

void cosim_unwatch_signals(void) {
    if (!watching) return;
    for (int i = 0; i < 3; i++) sigaction(WATCHED[i], &previous[i], NULL);
    watch_flag = NULL;
    watching = 0;
}

/* Threads for the parallel doSteps: each worker makes the doSteps of its ``thread`` number at
 * every step, so an instance is only ever called by one thread; the calling thread makes those
 * of thread 0 (and waits for the others). */
typedef struct {
    struct Pool *pool;
    int thread;
} Worker;

typedef struct Pool {
    int workers;
    pthread_t *tid;
    Worker *args;
    pthread_mutex_t mu;
    pthread_cond_t go, done;
    long generation;
    int pending, quit;
    const Program *program;
    double t, h;
} Pool;

static void steps_of(const Program *p, int thread, double t, double h) {
    for (int i = 0; i < p->n_parallel; i++)
        if (p->ops[i].thread == thread) p->statuses[i] = operate(&p->ops[i], t, h);
}

/* A pause in a spin-wait; a thread spins up to SPIN rounds before it sleeps on a condition
 * variable (waking a sleeping thread costs tens of µs on a VM, the length of a fast step). */
#define SPIN 20000
static inline void pause_a_little(void) {
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#endif
}

static void *work(void *arg) {
    Worker *w = arg;
    Pool *pool = w->pool;
    long seen = 0;
    for (;;) {
        for (int i = 0; i < SPIN && __atomic_load_n(&pool->generation, __ATOMIC_ACQUIRE) == seen
                                 && !__atomic_load_n(&pool->quit, __ATOMIC_ACQUIRE); i++)
            pause_a_little();
        pthread_mutex_lock(&pool->mu);
        while (__atomic_load_n(&pool->generation, __ATOMIC_ACQUIRE) == seen && !pool->quit)
            pthread_cond_wait(&pool->go, &pool->mu);
        int quit = pool->quit;
        pthread_mutex_unlock(&pool->mu);
        if (quit) return NULL;
        seen = __atomic_load_n(&pool->generation, __ATOMIC_ACQUIRE);
        steps_of(pool->program, w->thread, pool->t, pool->h);
        if (__atomic_sub_fetch(&pool->pending, 1, __ATOMIC_ACQ_REL) == 0) {
            pthread_mutex_lock(&pool->mu);
            pthread_cond_signal(&pool->done);
            pthread_mutex_unlock(&pool->mu);
        }
    }
}

static void parallel_steps(const Program *p, double t, double h) {
    Pool *pool = p->pool;
    pthread_mutex_lock(&pool->mu);
    pool->program = p;
    pool->t = t;
    pool->h = h;
    __atomic_store_n(&pool->pending, pool->workers, __ATOMIC_RELEASE);
    __atomic_add_fetch(&pool->generation, 1, __ATOMIC_ACQ_REL);
    pthread_cond_broadcast(&pool->go);
    pthread_mutex_unlock(&pool->mu);
    steps_of(p, 0, t, h);
    for (int i = 0; i < SPIN && __atomic_load_n(&pool->pending, __ATOMIC_ACQUIRE) > 0; i++) pause_a_little();
    pthread_mutex_lock(&pool->mu);
    while (__atomic_load_n(&pool->pending, __ATOMIC_ACQUIRE) > 0) pthread_cond_wait(&pool->done, &pool->mu);
    pthread_mutex_unlock(&pool->mu);
}

void cosim_pool_free(Pool *pool);

/* A pool of threads - 1 workers (NULL if they cannot be started). */
Pool *cosim_pool_new(int threads) {
    Pool *pool = calloc(1, sizeof(Pool));
    if (pool == NULL) return NULL;
    pool->tid = calloc((size_t)threads, sizeof(pthread_t));
    Worker *workers = pool->args = calloc((size_t)threads, sizeof(Worker));
    pthread_mutex_init(&pool->mu, NULL);
    pthread_cond_init(&pool->go, NULL);
    pthread_cond_init(&pool->done, NULL);
    if (pool->tid == NULL || workers == NULL) {
        cosim_pool_free(pool);
        return NULL;
    }
    for (int i = 1; i < threads; i++) {
        workers[i].pool = pool;
        workers[i].thread = i;
        if (pthread_create(&pool->tid[pool->workers], NULL, work, &workers[i]) != 0) {
            cosim_pool_free(pool);
            return NULL;
        }
        pool->workers++;
    }
    return pool;
}

void cosim_pool_free(Pool *pool) {
    if (pool == NULL) return;
    pthread_mutex_lock(&pool->mu);
    __atomic_store_n(&pool->quit, 1, __ATOMIC_RELEASE);
    pthread_cond_broadcast(&pool->go);
    pthread_mutex_unlock(&pool->mu);
    for (int i = 0; i < pool->workers; i++) pthread_join(pool->tid[i], NULL);
    pthread_mutex_destroy(&pool->mu);
    pthread_cond_destroy(&pool->go);
    pthread_cond_destroy(&pool->done);
    free(pool->tid);
    free(pool->args);
    free(pool);
}
