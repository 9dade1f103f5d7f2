/* A C host with no Python that runs several FMUs in one process, as a model with several blocks
 * does (tests/slaves/test_together.py compiles it with the system compiler).
 *
 *   together_host MODE COUNT SPEC...
 *     SPEC: set VR VALUE                         fmi2SetReal on the next FMU's instance before initialisation
 *           fmu DIR IDENTIFIER GUID OUTPUT_VR    DIR/binaries/linux64/IDENTIFIER.so (dlopen RTLD_LOCAL;
 *                                                Windows, built with mingw-w64: binaries\\win64\\IDENTIFIER.dll)
 *
 *   threads      every FMU on its own thread, all released at once: instantiate, set up,
 *                initialise, COUNT steps of 0.1 s, read OUTPUT_VR, free (the first
 *                instantiations of several FMUs at the same time)
 *   sequence     one FMU after the other: load, instantiate, COUNT steps, read, free, unload
 *   delete       as sequence, and each FMU's folder deleted once it is unloaded (fmpy does it)
 *   cycles       FMU 0: 20 instantiate/free cycles, then COUNT more; "rss-growth BYTES" over those
 *   states       FMU 0: COUNT steps, each followed by fmi2GetFMUstate with the previous state passed
 *                back (FMI 2.0 §2.1.8); "rss-growth BYTES" over the last COUNT - 20 of them
 *   bad-states   FMU 0 initialised, then fmi2DeSerializeFMUstate of foreign, truncated, random and
 *                empty bytes (the foreign ones: FMU 1's serialised state, when given), then its own
 *                state deserialised and set, and a step
 *   bad-parameter  FMU 0 set up, in initialisation mode its Integer OUTPUT_VR set to COUNT, then
 *                fmi2ExitInitializationMode, fmi2Reset and a second initialisation
 *   sigint-thread  FMU 0 instantiated and stepped on a thread that has ended, then SIGINT raised
 *   sigint-main  the same on the main thread (Windows: no signal raised; the disposition said is
 *                that of the C runtime Python uses, ucrtbase.dll, and the exit is 0)
 *   sigint-handler the host's own SIGINT handler installed first; after the FMU, SIGINT raised
 *
 * Every call has loggingOn = fmi2False, as most hosts' default.  Output, one line each:
 * "log INSTANCE STATUS CATEGORY MESSAGE" for each logger call, "result FMU WHAT VALUE" for each
 * outcome (an fmi2Status number, "null", "instance" or an output value with %.17g), "rss-growth
 * BYTES".  Exit 0 when every call succeeded, 1 otherwise, 2 for usage errors; the sigint modes
 * print "survived" and exit 3 if the process outlives the signal.
 */
#define _GNU_SOURCE
#include <pthread.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2host.h" /* Windows: built with mingw-w64 (-static: winpthreads inside), modes threads, sequence,
                      * sigint-main */
#ifndef _WIN32
#include <ftw.h>
#include <unistd.h>
#endif

typedef void *State;

typedef struct {
    const char *dir, *identifier, *guid;
    unsigned output;
    void *library;
    Component (*instantiate)(const char *, int, const char *, const char *, const Callbacks *, int, int);
    Status (*setup)(Component, int, double, double, int, double);
    Status (*enter)(Component);
    Status (*exit_init)(Component);
    Status (*get)(Component, const unsigned *, size_t, double *);
    Status (*step)(Component, double, double, int);
    Status (*terminate)(Component);
    void (*free_instance)(Component);
    Status (*get_state)(Component, State *);
    Status (*free_state)(Component, State *);
    Status (*set_state)(Component, State);
    Status (*set_integer)(Component, const unsigned *, size_t, const int *);
    Status (*reset)(Component);
    Status (*state_size)(Component, State, size_t *);
    Status (*serialize)(Component, State, char *, size_t);
    Status (*deserialize)(Component, const char *, size_t, State *);
    Status (*set_real)(Component, const unsigned *, size_t, const double *);
    unsigned set_vr[4];
    double set_value[4];
    int set_count;
    int index;
    int ok;
} Fmu;

enum { MAX = 16 };
static Fmu fmus[MAX];
static int fmu_count;
static long count;
static pthread_mutex_t output_lock = PTHREAD_MUTEX_INITIALIZER;
static pthread_barrier_t start_together;
static int together; /* threads mode: every run waits for the others to start */

static void say(const char *format, ...) {
    va_list args;
    va_start(args, format);
    pthread_mutex_lock(&output_lock);
    vprintf(format, args);
    fflush(stdout);
    pthread_mutex_unlock(&output_lock);
    va_end(args);
}

static void logger(void *env, const char *instance, int status, const char *category, const char *format, ...) {
    (void)env;
    char message[8192];
    va_list args;
    va_start(args, format);
    vsnprintf(message, sizeof message, format, args);
    va_end(args);
    message[strcspn(message, "\n")] = '\0';
    say("log %s %d %s %s\n", instance ? instance : "?", status, category ? category : "", message);
}

static const Callbacks callbacks = {logger, calloc, free, NULL, NULL};

static void *symbol(void *library, const char *name) {
    void *found = dlsym(library, name);
    if (found == NULL) {
        fprintf(stderr, "no %s: %s\n", name, dlerror());
        exit(2);
    }
    return found;
}

static void load(Fmu *f) {
    char path[4200];
    snprintf(path, sizeof path, BINARY, f->dir, f->identifier);
    f->library = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (f->library == NULL) {
        fprintf(stderr, "dlopen failed: %s\n", dlerror());
        exit(2);
    }
    *(void **)&f->instantiate = symbol(f->library, "fmi2Instantiate");
    *(void **)&f->setup = symbol(f->library, "fmi2SetupExperiment");
    *(void **)&f->enter = symbol(f->library, "fmi2EnterInitializationMode");
    *(void **)&f->exit_init = symbol(f->library, "fmi2ExitInitializationMode");
    *(void **)&f->get = symbol(f->library, "fmi2GetReal");
    *(void **)&f->set_real = symbol(f->library, "fmi2SetReal");
    *(void **)&f->step = symbol(f->library, "fmi2DoStep");
    *(void **)&f->terminate = symbol(f->library, "fmi2Terminate");
    *(void **)&f->free_instance = symbol(f->library, "fmi2FreeInstance");
    *(void **)&f->get_state = symbol(f->library, "fmi2GetFMUstate");
    *(void **)&f->free_state = symbol(f->library, "fmi2FreeFMUstate");
    *(void **)&f->set_state = symbol(f->library, "fmi2SetFMUstate");
    *(void **)&f->set_integer = symbol(f->library, "fmi2SetInteger");
    *(void **)&f->reset = symbol(f->library, "fmi2Reset");
    *(void **)&f->state_size = symbol(f->library, "fmi2SerializedFMUstateSize");
    *(void **)&f->serialize = symbol(f->library, "fmi2SerializeFMUstate");
    *(void **)&f->deserialize = symbol(f->library, "fmi2DeSerializeFMUstate");
}

/* fmi2Instantiate; NULL (said) if it failed. */
static Component instantiate(Fmu *f) {
    char location[4300], name[32];
    snprintf(location, sizeof location, RESOURCES, f->dir);
    snprintf(name, sizeof name, "instance%d", f->index);
    Component c = f->instantiate(name, 1 /* fmi2CoSimulation */, f->guid, location, &callbacks, 0, 0);
    if (c == NULL) say("result %d instantiate null\n", f->index);
    return c;
}

static int check(Fmu *f, Status status, const char *call) {
    if (status > 1) say("result %d %s %d\n", f->index, call, status);
    return status <= 1;
}

/* The `set` values, set up and initialise an instance. */
static int initialise(Fmu *f, Component c) {
    for (int k = 0; k < f->set_count; k++)
        if (!check(f, f->set_real(c, &f->set_vr[k], 1, &f->set_value[k]), "set")) return 0;
    return check(f, f->setup(c, 0, 0.0, 0.0, 0, 0.0), "setup") && check(f, f->enter(c), "enter") &&
           check(f, f->exit_init(c), "exit");
}

/* Instantiate, initialise, COUNT steps, read the output, free: the FMU's whole run. */
static void *run(void *argument) {
    Fmu *f = argument;
    if (together) pthread_barrier_wait(&start_together);
    f->ok = 0;
    Component c = instantiate(f);
    if (c == NULL) return NULL;
    int ok = initialise(f, c);
    for (long k = 0; ok && k < count; k++) ok = check(f, f->step(c, 0.1 * (double)k, 0.1, 1), "step");
    double value = 0;
    if (ok) ok = check(f, f->get(c, &f->output, 1, &value), "get");
    if (ok) say("result %d output %.17g\n", f->index, value);
    f->terminate(c);
    f->free_instance(c);
    f->ok = ok;
    return NULL;
}

#ifndef _WIN32
static int remove_entry(const char *path, const struct stat *status, int flag, struct FTW *walk) {
    (void)status, (void)flag, (void)walk;
    return remove(path);
}

static long resident_bytes(void) {
    long pages = 0, resident = 0;
    FILE *statm = fopen("/proc/self/statm", "r");
    if (statm == NULL || fscanf(statm, "%ld %ld", &pages, &resident) != 2) resident = 0;
    if (statm != NULL) fclose(statm);
    return resident * sysconf(_SC_PAGESIZE);
}
#endif

#ifndef _WIN32
static int cycles(Fmu *f) {
    long before = 0;
    for (long k = 0; k < 20 + count; k++) {
        if (k == 20) before = resident_bytes();
        Component c = instantiate(f);
        if (c == NULL || !initialise(f, c) || !check(f, f->step(c, 0.0, 0.1, 1), "step")) return 0;
        f->terminate(c);
        f->free_instance(c);
    }
    say("rss-growth %ld\n", resident_bytes() - before);
    return 1;
}

static int states(Fmu *f) {
    Component c = instantiate(f);
    if (c == NULL || !initialise(f, c)) return 0;
    State state = NULL;
    long before = 0;
    for (long k = 0; k < count; k++) {
        if (k == 20) before = resident_bytes();
        if (!check(f, f->step(c, 0.1 * (double)k, 0.1, 1), "step") ||
            !check(f, f->get_state(c, &state), "get_state"))
            return 0;
    }
    say("rss-growth %ld\n", resident_bytes() - before);
    int ok = check(f, f->free_state(c, &state), "free_state");
    f->terminate(c);
    f->free_instance(c);
    return ok;
}

#endif

/* Serialised state of an initialised instance of f, into *bytes (malloc'ed); its size. */
static size_t serialised(Fmu *f, char **bytes) {
    Component c = instantiate(f);
    State state = NULL;
    size_t size = 0;
    if (c == NULL || !initialise(f, c) || !check(f, f->get_state(c, &state), "get_state") ||
        !check(f, f->state_size(c, state, &size), "state_size"))
        exit(1);
    *bytes = malloc(size + 1);
    if (!check(f, f->serialize(c, state, *bytes, size), "serialize")) exit(1);
    f->free_state(c, &state);
    f->free_instance(c);
    return size;
}

static int bad_states(Fmu *f, Fmu *foreign) {
    char *own = NULL, *other = NULL, random_bytes[256];
    size_t own_size = serialised(f, &own), other_size = foreign != NULL ? serialised(foreign, &other) : 0;
    srand(7);
    for (size_t i = 0; i < sizeof random_bytes; i++) random_bytes[i] = (char)rand();
    struct { const char *name; const char *bytes; size_t size; } cases[] = {
        {"foreign", other, other_size}, {"truncated", own, own_size / 2}, {"header", own, 20},
        {"random", random_bytes, sizeof random_bytes}, {"empty", own, 0}};
    Component c = instantiate(f);
    if (c == NULL || !initialise(f, c)) return 0;
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        if (cases[i].bytes == NULL) continue;
        State state = NULL;
        say("case %s\n", cases[i].name);
        Status status = f->deserialize(c, cases[i].bytes, cases[i].size, &state);
        say("result %d deserialize-%s %d\n", f->index, cases[i].name, status);
        if (status <= 1) f->free_state(c, &state);
    }
    say("case after\n");
    State good = NULL;
    Status status = f->deserialize(c, own, own_size, &good);
    say("result %d deserialize-own %d\n", f->index, status);
    if (status <= 1) {
        status = f->set_state(c, good);
        say("result %d set-own %d\n", f->index, status);
        f->free_state(c, &good);
    }
    status = f->step(c, 0.0, 0.1, 1);
    say("result %d step-after %d\n", f->index, status);
    f->free_instance(c);
    free(own);
    free(other);
    return 1;
}

/* An invalid Integer parameter refused at fmi2ExitInitializationMode; the instance reset and used again. */
static int bad_parameter(Fmu *f) {
    Component c = instantiate(f);
    if (c == NULL || !check(f, f->setup(c, 0, 0.0, 0.0, 0, 0.0), "setup") || !check(f, f->enter(c), "enter")) return 0;
    int value = (int)count;
    say("result %d set %d\n", f->index, f->set_integer(c, &f->output, 1, &value));
    say("result %d exit %d\n", f->index, f->exit_init(c));
    say("result %d reset %d\n", f->index, f->reset(c));
    int ok = initialise(f, c) && check(f, f->step(c, 0.0, 0.1, 1), "step");
    say("result %d again %d\n", f->index, ok ? 0 : 3);
    f->free_instance(c);
    return 1;
}

static volatile sig_atomic_t host_signals;
static void host_handler(int number) {
    (void)number;
    host_signals++;
}

int main(int argc, char **argv) {
    if (argc < 3) {
        fprintf(stderr, "usage: %s MODE COUNT SPEC...\n", argv[0]);
        return 2;
    }
    const char *mode = argv[1];
    count = strtol(argv[2], NULL, 10);
    for (int a = 3; a < argc; a += 5) {
        if (!strcmp(argv[a], "set") && a + 2 < argc && fmus[fmu_count].set_count < 4) {
            Fmu *next = &fmus[fmu_count];
            next->set_vr[next->set_count] = (unsigned)strtoul(argv[a + 1], NULL, 10);
            next->set_value[next->set_count++] = strtod(argv[a + 2], NULL);
            a -= 2;
            continue;
        }
        if (strcmp(argv[a], "fmu") != 0 || a + 4 >= argc || fmu_count == MAX) {
            fprintf(stderr, "bad FMU at %s\n", argv[a]);
            return 2;
        }
        Fmu *f = &fmus[fmu_count];
        f->dir = argv[a + 1];
        f->identifier = argv[a + 2];
        f->guid = argv[a + 3];
        f->output = (unsigned)strtoul(argv[a + 4], NULL, 10);
        f->index = fmu_count++;
    }
    if (fmu_count == 0) return 2;
    int ok = 1;
    if (!strcmp(mode, "threads")) {
        pthread_t threads[MAX];
        pthread_barrier_init(&start_together, NULL, (unsigned)fmu_count);
        for (int i = 0; i < fmu_count; i++) load(&fmus[i]);
        together = 1;
        for (int i = 0; i < fmu_count; i++) {
            pthread_create(&threads[i], NULL, run, &fmus[i]);
        }
        for (int i = 0; i < fmu_count; i++) {
            pthread_join(threads[i], NULL);
            ok &= fmus[i].ok == 1;
        }
    } else if (!strcmp(mode, "sequence") || !strcmp(mode, "delete")) {
        for (int i = 0; i < fmu_count; i++) {
            load(&fmus[i]);
            run(&fmus[i]);
            ok &= fmus[i].ok == 1;
            dlclose(fmus[i].library);
#ifndef _WIN32
            if (!strcmp(mode, "delete")) nftw(fmus[i].dir, remove_entry, 16, FTW_DEPTH | FTW_PHYS);
#endif
        }
#ifndef _WIN32
    } else if (!strcmp(mode, "cycles")) {
        load(&fmus[0]);
        ok = cycles(&fmus[0]);
    } else if (!strcmp(mode, "states")) {
        load(&fmus[0]);
        ok = states(&fmus[0]);
#endif
    } else if (!strcmp(mode, "bad-parameter")) {
        load(&fmus[0]);
        ok = bad_parameter(&fmus[0]);
    } else if (!strcmp(mode, "bad-states")) {
        for (int i = 0; i < fmu_count; i++) load(&fmus[i]);
        ok = bad_states(&fmus[0], fmu_count > 1 ? &fmus[1] : NULL);
    } else if (!strncmp(mode, "sigint-", 7)) {
        if (!strcmp(mode, "sigint-handler")) signal(SIGINT, host_handler);
        load(&fmus[0]);
        if (!strcmp(mode, "sigint-thread")) {
            pthread_t thread;
            pthread_create(&thread, NULL, run, &fmus[0]);
            pthread_join(thread, NULL);
        } else {
            run(&fmus[0]);
        }
        ok = fmus[0].ok == 1;
#ifdef _WIN32
        /* The disposition in the C runtime Python uses (ucrtbase.dll); this host's own is another's */
        typedef void (*Handler)(int);
        Handler (*crt_signal)(int, Handler) = (Handler(*)(int, Handler))(void *)GetProcAddress(
            GetModuleHandleA("ucrtbase.dll"), "signal");
        Handler now = crt_signal != NULL ? crt_signal(SIGINT, SIG_DFL) : SIG_DFL;
        if (crt_signal != NULL) crt_signal(SIGINT, now);
        say("sigint-disposition %s\n", now == SIG_DFL ? "default" : "other");
        return ok ? 0 : 1;
#else
        struct sigaction now;
        sigaction(SIGINT, NULL, &now);
        say("sigint-disposition %s\n", now.sa_handler == SIG_DFL ? "default" : now.sa_handler == host_handler ? "host"
                                       : "other");
        raise(SIGINT);
        sleep(2);
        say("host-handler-calls %d\n", (int)host_signals);
        say("survived\n");
        return ok ? 3 : 1;
#endif
    } else {
        fprintf(stderr, "unknown mode %s\n", mode);
        return 2;
    }
    return ok ? 0 : 1;
}
