/* What the C test hosts tests/dropin_host.c and tests/together_host.c (and benchmarks/step_host.c) share: loading an FMU's
 * binary on Linux (dlopen) and Windows (LoadLibrary, built with mingw-w64), and the FMI 2.0
 * types they call it with. */
#ifndef GREYFMU_TESTS_FMI2HOST_H
#define GREYFMU_TESTS_FMI2HOST_H

#include <stdio.h>
#include <stdlib.h>

#ifdef _WIN32
#include <windows.h>
#define dlopen(path, mode) ((void *)LoadLibraryExA(path, NULL, LOAD_WITH_ALTERED_SEARCH_PATH))
#define dlsym(library, name) ((void *)GetProcAddress((HMODULE)(library), name))
#define dlclose(library) FreeLibrary((HMODULE)(library))
#define BINARY "%s\\binaries\\win64\\%s.dll"
#define RESOURCES "file:///%s/resources"
static const char *dlerror(void) {
    static char message[64];
    snprintf(message, sizeof message, "Windows error %lu", GetLastError());
    return message;
}
#else
#include <dlfcn.h>
#define BINARY "%s/binaries/linux64/%s.so"
#define RESOURCES "file://%s/resources"
#endif

typedef void *Component;
typedef int Status; /* fmi2OK = 0, fmi2Warning = 1 */
typedef struct {
    void (*logger)(void *, const char *, int, const char *, const char *, ...);
    void *(*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void *);
    void (*stepFinished)(void *, int);
    void *componentEnvironment;
} Callbacks;

#ifdef FMI2HOST_STDERR_LOGGER
/* What tests/dropin_host.c and benchmarks/step_host.c share: a logger printing each message on
 * stderr, and dlsym or exit(1). */
#include <stdarg.h>

static void logger(void *env, const char *instance, int status, const char *category, const char *format, ...) {
    (void)env;
    va_list args;
    va_start(args, format);
    fprintf(stderr, "[%s] status %d %s: ", instance ? instance : "?", status, category ? category : "");
    vfprintf(stderr, format, args);
    fprintf(stderr, "\n");
    va_end(args);
}

static void *symbol(void *library, const char *name) {
    void *found = dlsym(library, name);
    if (!found) {
        fprintf(stderr, "no %s: %s\n", name, dlerror());
        exit(1);
    }
    return found;
}
#endif

#endif
