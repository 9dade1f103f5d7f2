/* The per-step cost of FMI 2.0 Co-Simulation FMUs in a C host with no Python of its own (the host
 * of benchmarks/bench_slave_step.py; our FMUs' loader starts Python in it).
 *
 *   step_host STEPS ROUNDS STEP fmu DIR IDENTIFIER GUID NIN IN_VR... NOUT OUT_VR... [fmu ...]
 *
 * Each FMU is loaded (dlopen of DIR/binaries/linux64/IDENTIFIER.so), instantiated, set up at t = 0
 * and initialised, in the order given (a plain pythonfmu FMU needs the libpython an FMU of ours
 * loaded: give ours first).  Then ROUNDS rounds: in each, every FMU in turn makes STEPS steps of
 * STEP, each one fmi2SetReal of its inputs (the values 1, 0.5, 0.25, ...), one fmi2DoStep and one
 * fmi2GetReal of its outputs, the FMUs interleaved so that a busy machine slows them alike.
 * Prints one line per FMU: its identifier, then the CPU time per step of every round in µs
 * (CLOCK_PROCESS_CPUTIME_ID: the host has one thread).  Exit 1 if an FMI call fails.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define FMI2HOST_STDERR_LOGGER
#include "../tests/fmi2host.h"

enum { MAX_FMUS = 16, MAX_PORTS = 64, MAX_ROUNDS = 100 };

typedef struct {
    const char *identifier;
    Component c;
    Status (*get)(Component, const unsigned *, size_t, double *);
    Status (*set)(Component, const unsigned *, size_t, const double *);
    Status (*step)(Component, double, double, int);
    unsigned in[MAX_PORTS], out[MAX_PORTS];
    size_t n_in, n_out;
    double t;
    double us[MAX_ROUNDS];
} Fmu;

static void ok(Status status, const char *call, const char *identifier) {
    if (status > 1) {
        fprintf(stderr, "%s of %s returned status %d\n", call, identifier, status);
        exit(1);
    }
}

static void start(Fmu *f, const char *dir, const char *guid) {
    static const Callbacks callbacks = {logger, calloc, free, NULL, NULL};
    char path[4096], location[4200];
    snprintf(path, sizeof path, BINARY, dir, f->identifier);
    void *library = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!library) {
        fprintf(stderr, "dlopen failed: %s\n", dlerror());
        exit(1);
    }
    Component (*instantiate)(const char *, int, const char *, const char *, const Callbacks *, int, int);
    Status (*setup)(Component, int, double, double, int, double);
    Status (*enter)(Component);
    Status (*exit_init)(Component);
    *(void **)&instantiate = symbol(library, "fmi2Instantiate");
    *(void **)&setup = symbol(library, "fmi2SetupExperiment");
    *(void **)&enter = symbol(library, "fmi2EnterInitializationMode");
    *(void **)&exit_init = symbol(library, "fmi2ExitInitializationMode");
    *(void **)&f->get = symbol(library, "fmi2GetReal");
    *(void **)&f->set = symbol(library, "fmi2SetReal");
    *(void **)&f->step = symbol(library, "fmi2DoStep");
    snprintf(location, sizeof location, RESOURCES, dir);
    f->c = instantiate(f->identifier, 1 /* fmi2CoSimulation */, guid, location, &callbacks, 0, 0);
    if (!f->c) {
        fprintf(stderr, "fmi2Instantiate of %s returned NULL\n", f->identifier);
        exit(1);
    }
    ok(setup(f->c, 0, 0.0, 0.0, 0, 0.0), "fmi2SetupExperiment", f->identifier);
    ok(enter(f->c), "fmi2EnterInitializationMode", f->identifier);
    ok(exit_init(f->c), "fmi2ExitInitializationMode", f->identifier);
}

static double cpu_seconds(void) {
    struct timespec now;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &now);
    return (double)now.tv_sec + 1e-9 * (double)now.tv_nsec;
}

static size_t ports(char **argv, int *a, int argc, unsigned *vrs) {
    if (*a >= argc) exit(2);
    size_t n = (size_t)atoi(argv[(*a)++]);
    if (n > MAX_PORTS || *a + (int)n > argc) exit(2);
    for (size_t k = 0; k < n; k++) vrs[k] = (unsigned)atoi(argv[(*a)++]);
    return n;
}

int main(int argc, char **argv) {
    static Fmu fmus[MAX_FMUS];
    int count = 0;
    if (argc < 5) {
        fprintf(stderr, "usage: %s STEPS ROUNDS STEP fmu DIR IDENTIFIER GUID NIN IN_VR... NOUT OUT_VR...\n", argv[0]);
        return 2;
    }
    long steps = atol(argv[1]);
    int rounds = atoi(argv[2]);
    double h = atof(argv[3]);
    if (rounds < 1 || rounds > MAX_ROUNDS || steps < 1) return 2;
    for (int a = 4; a < argc;) {
        if (strcmp(argv[a], "fmu") || a + 3 >= argc || count == MAX_FMUS) {
            fprintf(stderr, "bad command at %s\n", argv[a]);
            return 2;
        }
        Fmu *f = &fmus[count++];
        const char *dir = argv[a + 1], *guid = argv[a + 3];
        f->identifier = argv[a + 2];
        a += 4;
        f->n_in = ports(argv, &a, argc, f->in);
        f->n_out = ports(argv, &a, argc, f->out);
        start(f, dir, guid);
    }
    double values[MAX_PORTS], outputs[MAX_PORTS];
    for (int k = 0; k < MAX_PORTS; k++) values[k] = 1.0 / (double)(1 << (k % 16));
    for (int round = 0; round < rounds; round++)
        for (int i = 0; i < count; i++) {
            Fmu *f = &fmus[i];
            Status status = 0;
            double began = cpu_seconds();
            for (long k = 0; k < steps; k++) {
                status |= f->set(f->c, f->in, f->n_in, values);
                status |= f->step(f->c, f->t, h, 1);
                status |= f->get(f->c, f->out, f->n_out, outputs);
                f->t += h;
            }
            f->us[round] = (cpu_seconds() - began) / (double)steps * 1e6;
            ok(status & ~1, "a call", f->identifier);
        }
    for (int i = 0; i < count; i++) {
        printf("%s", fmus[i].identifier);
        for (int round = 0; round < rounds; round++) printf(" %.4f", fmus[i].us[round]);
        printf("\n");
    }
    return 0;
}
