/* A minimal FMI 2.0 Co-Simulation host in C, with no Python: the drop-in test host of
 * tests/test_dropin_host.py (compiled there with the system compiler).
 *
 *   dropin_host OUT.csv START STOP STEP COMMAND...
 *     fmu DIR IDENTIFIER GUID        load DIR/binaries/linux64/IDENTIFIER.so (dlopen; on Windows
 *                                    DIR\binaries\win64\IDENTIFIER.dll, LoadLibrary), instance i = 0, 1, ...
 *     set I VR VALUE                 fmi2SetReal before initialisation
 *     connect I VR J VR              output VR of instance I drives input VR of instance J
 *     record I VR NAME               a CSV column
 *     embed LIBPYTHON init|load      (Linux, before any fmu) dlopen LIBPYTHON RTLD_LOCAL, as a host
 *                                    embedding Python does, and with init Py_InitializeEx(0) (the
 *                                    main thread keeps the GIL)
 *
 * Fixed-step Jacobi: inputs are set from the outputs at t, then every instance steps [t, t+h];
 * t_k = START + k*STEP.  In initialisation mode the connections are propagated as many times as
 * there are instances (settles any acyclic feedthrough chain).  Before the first fmi2Instantiate
 * it prints "python-before-instantiate: yes|no" (a libpython mapped in /proc/self/maps; on
 * Windows a loaded python*.dll), after
 * the last one "python-after-instantiate: yes|no" and (Linux) "libpython-files: N", the number of
 * distinct libpython files mapped.  Exit 0 on success, 1 if an FMI call fails, 2 for usage errors.
 */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define FMI2HOST_STDERR_LOGGER
#include "fmi2host.h"

#ifdef _WIN32
#include <psapi.h>
static int python_mapped(void) {
    HMODULE modules[1024];
    DWORD needed = 0;
    EnumProcessModules(GetCurrentProcess(), modules, sizeof modules, &needed);
    for (DWORD i = 0; i < needed / sizeof(HMODULE) && i < 1024; i++) {
        char name[MAX_PATH];
        if (GetModuleBaseNameA(GetCurrentProcess(), modules[i], name, sizeof name) && _strnicmp(name, "python", 6) == 0)
            return 1;
    }
    return 0;
}
#else
static int python_mapped(void) {
    FILE *maps = fopen("/proc/self/maps", "r");
    char line[4096];
    int found = 0;
    while (maps && fgets(line, sizeof line, maps))
        if (strstr(line, "libpython")) found = 1;
    if (maps) fclose(maps);
    return found;
}

/* The number of distinct libpython files in /proc/self/maps (a second interpreter makes it 2). */
static int libpython_files(void) {
    FILE *maps = fopen("/proc/self/maps", "r");
    char line[4096], files[8][4096];
    int count = 0;
    while (maps && fgets(line, sizeof line, maps)) {
        char *file = strchr(line, '/');
        if (file == NULL || strstr(file, "libpython") == NULL) continue;
        file[strcspn(file, "\n")] = '\0';
        int seen = 0;
        for (int k = 0; k < count; k++) seen |= !strcmp(files[k], file);
        if (!seen && count < 8) snprintf(files[count++], sizeof files[0], "%s", file);
    }
    if (maps) fclose(maps);
    return count;
}
#endif

typedef struct {
    void *library;
    Component c;
    Component (*instantiate)(const char *, int, const char *, const char *, const Callbacks *, int, int);
    Status (*setup)(Component, int, double, double, int, double);
    Status (*enter)(Component);
    Status (*exit_init)(Component);
    Status (*get)(Component, const unsigned *, size_t, double *);
    Status (*set)(Component, const unsigned *, size_t, const double *);
    Status (*step)(Component, double, double, int);
    Status (*terminate)(Component);
    void (*free_instance)(Component);
} Fmu;

enum { MAX = 32 };
static Fmu fmus[MAX];
static int fmu_count;
static struct { int from; unsigned from_vr; int to; unsigned to_vr; } connections[MAX * 4];
static int connection_count;
static struct { int i; unsigned vr; const char *name; } columns[MAX * 8];
static int column_count;

static int check(Status status, const char *call, int i, double t) {
    if (status > 1) {
        fprintf(stderr, "%s of instance %d failed with status %d at t = %g\n", call, i, status, t);
        return 0;
    }
    return 1;
}

#ifndef _WIN32
/* What a host embedding Python does: its libpython loaded RTLD_LOCAL, initialised if `init`. */
static void embed(const char *libpython, int init) {
    void *library = dlopen(libpython, RTLD_NOW | RTLD_LOCAL);
    if (!library) {
        fprintf(stderr, "dlopen failed: %s\n", dlerror());
        exit(1);
    }
    if (init) ((void (*)(int))symbol(library, "Py_InitializeEx"))(0);
}
#endif

static void load(const char *dir, const char *identifier) {
    char path[4096];
    snprintf(path, sizeof path, BINARY, dir, identifier);
    Fmu *f = &fmus[fmu_count++];
    f->library = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!f->library) {
        fprintf(stderr, "dlopen failed: %s\n", dlerror());
        exit(1);
    }
    *(void **)&f->instantiate = symbol(f->library, "fmi2Instantiate");
    *(void **)&f->setup = symbol(f->library, "fmi2SetupExperiment");
    *(void **)&f->enter = symbol(f->library, "fmi2EnterInitializationMode");
    *(void **)&f->exit_init = symbol(f->library, "fmi2ExitInitializationMode");
    *(void **)&f->get = symbol(f->library, "fmi2GetReal");
    *(void **)&f->set = symbol(f->library, "fmi2SetReal");
    *(void **)&f->step = symbol(f->library, "fmi2DoStep");
    *(void **)&f->terminate = symbol(f->library, "fmi2Terminate");
    *(void **)&f->free_instance = symbol(f->library, "fmi2FreeInstance");
}

static int propagate(double t) {
    for (int k = 0; k < connection_count; k++) {
        double value;
        if (!check(fmus[connections[k].from].get(fmus[connections[k].from].c, &connections[k].from_vr, 1, &value),
                   "fmi2GetReal", connections[k].from, t) ||
            !check(fmus[connections[k].to].set(fmus[connections[k].to].c, &connections[k].to_vr, 1, &value),
                   "fmi2SetReal", connections[k].to, t))
            return 0;
    }
    return 1;
}

static int record(FILE *csv, double t) {
    fprintf(csv, "%.17g", t);
    for (int k = 0; k < column_count; k++) {
        double value;
        if (!check(fmus[columns[k].i].get(fmus[columns[k].i].c, &columns[k].vr, 1, &value), "fmi2GetReal",
                   columns[k].i, t))
            return 0;
        fprintf(csv, ",%.17g", value);
    }
    fprintf(csv, "\n");
    return 1;
}

int main(int argc, char **argv) {
    if (argc < 6) {
        fprintf(stderr, "usage: %s OUT.csv START STOP STEP COMMAND...\n", argv[0]);
        return 2;
    }
    double start = atof(argv[2]), stop = atof(argv[3]), h = atof(argv[4]);
    const char *dirs[MAX], *guids[MAX];
    struct { int i; unsigned vr; double value; } sets[MAX * 8];
    int set_count = 0;
    for (int a = 5; a < argc;) {
        if (!strcmp(argv[a], "fmu") && a + 3 < argc) {
            dirs[fmu_count] = argv[a + 1];
            guids[fmu_count] = argv[a + 3];
            load(argv[a + 1], argv[a + 2]);
            a += 4;
        } else if (!strcmp(argv[a], "set") && a + 3 < argc) {
            sets[set_count].i = atoi(argv[a + 1]);
            sets[set_count].vr = (unsigned)atoi(argv[a + 2]);
            sets[set_count++].value = atof(argv[a + 3]);
            a += 4;
        } else if (!strcmp(argv[a], "connect") && a + 4 < argc) {
            connections[connection_count].from = atoi(argv[a + 1]);
            connections[connection_count].from_vr = (unsigned)atoi(argv[a + 2]);
            connections[connection_count].to = atoi(argv[a + 3]);
            connections[connection_count++].to_vr = (unsigned)atoi(argv[a + 4]);
            a += 5;
#ifndef _WIN32
        } else if (!strcmp(argv[a], "embed") && a + 2 < argc) {
            embed(argv[a + 1], !strcmp(argv[a + 2], "init"));
            a += 3;
#endif
        } else if (!strcmp(argv[a], "record") && a + 3 < argc) {
            columns[column_count].i = atoi(argv[a + 1]);
            columns[column_count].vr = (unsigned)atoi(argv[a + 2]);
            columns[column_count++].name = argv[a + 3];
            a += 4;
        } else {
            fprintf(stderr, "bad command at %s\n", argv[a]);
            return 2;
        }
    }
    printf("python-before-instantiate: %s\n", python_mapped() ? "yes" : "no");
    fflush(stdout);
    Callbacks callbacks = {logger, calloc, free, NULL, NULL};
    for (int i = 0; i < fmu_count; i++) {
        char location[4200], name[32];
        snprintf(location, sizeof location, RESOURCES, dirs[i]);
        snprintf(name, sizeof name, "instance%d", i);
        fmus[i].c = fmus[i].instantiate(name, 1 /* fmi2CoSimulation */, guids[i], location, &callbacks, 0, 0);
        if (!fmus[i].c) {
            fprintf(stderr, "fmi2Instantiate of instance %d returned NULL\n", i);
            return 1;
        }
    }
    printf("python-after-instantiate: %s\n", python_mapped() ? "yes" : "no");
#ifndef _WIN32
    printf("libpython-files: %d\n", libpython_files());
#endif
    for (int i = 0; i < fmu_count; i++)
        if (!check(fmus[i].setup(fmus[i].c, 0, 0.0, start, 1, stop), "fmi2SetupExperiment", i, start)) return 1;
    for (int k = 0; k < set_count; k++)
        if (!check(fmus[sets[k].i].set(fmus[sets[k].i].c, &sets[k].vr, 1, &sets[k].value), "fmi2SetReal", sets[k].i,
                   start))
            return 1;
    for (int i = 0; i < fmu_count; i++)
        if (!check(fmus[i].enter(fmus[i].c), "fmi2EnterInitializationMode", i, start)) return 1;
    for (int pass = 0; pass < fmu_count; pass++)
        if (!propagate(start)) return 1;
    for (int i = 0; i < fmu_count; i++)
        if (!check(fmus[i].exit_init(fmus[i].c), "fmi2ExitInitializationMode", i, start)) return 1;
    FILE *csv = fopen(argv[1], "w");
    if (!csv) {
        perror(argv[1]);
        return 2;
    }
    fprintf(csv, "time");
    for (int k = 0; k < column_count; k++) fprintf(csv, ",%s", columns[k].name);
    fprintf(csv, "\n");
    if (!record(csv, start)) return 1;
    long steps = (long)((stop - start) / h + 0.5);
    for (long k = 0; k < steps; k++) {
        double t = start + (double)k * h;
        if (!propagate(t)) return 1;
        for (int i = 0; i < fmu_count; i++)
            if (!check(fmus[i].step(fmus[i].c, t, h, 1), "fmi2DoStep", i, t)) return 1;
        if (!record(csv, start + (double)(k + 1) * h)) return 1;
    }
    fclose(csv);
    for (int i = 0; i < fmu_count; i++) {
        fmus[i].terminate(fmus[i].c);
        fmus[i].free_instance(fmus[i].c);
    }
    for (int i = 0; i < fmu_count; i++) dlclose(fmus[i].library);
    return 0;
}
