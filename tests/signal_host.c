/* A C host in which a signal arrives while the FMU's loader queries a candidate Python
 * (compiled by tests/slaves/test_loader_query.py with the system compiler).
 *
 *   signal_host DIR IDENTIFIER GUID MILLISECONDS
 *     installs a SIGALRM handler without SA_RESTART (an interrupted poll or read returns EINTR),
 *     arms one SIGALRM after MILLISECONDS, then calls DIR/binaries/linux64/IDENTIFIER.so's
 *     fmi2Instantiate on the main thread.
 *
 * Output, one line each: "log STATUS CATEGORY MESSAGE" for each logger call, "signals N",
 * "result instance|null SECONDS" (the wall time of fmi2Instantiate), then "done".
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/time.h>
#include <time.h>

typedef void (*Logger)(void *, const char *, int, const char *, const char *, ...);
typedef struct {
    Logger logger;
    void *(*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void *);
    void (*stepFinished)(void *, int);
    void *componentEnvironment;
} Callbacks;
typedef void *(*Instantiate)(const char *, int, const char *, const char *, const Callbacks *, int, int);

static volatile sig_atomic_t signals;

static void on_alarm(int number) {
    (void)number;
    signals++;
}

static void logger(void *env, const char *name, int status, const char *category, const char *format, ...) {
    (void)env;
    (void)name;
    char message[16384];
    va_list args;
    va_start(args, format);
    vsnprintf(message, sizeof message, format, args);
    va_end(args);
    printf("log %d %s %s\n", status, category, message);
}

int main(int argc, char **argv) {
    if (argc != 5) {
        fprintf(stderr, "usage: signal_host DIR IDENTIFIER GUID MILLISECONDS\n");
        return 2;
    }
    char binary[4200], resources[4200];
    snprintf(binary, sizeof binary, "%s/binaries/linux64/%s.so", argv[1], argv[2]);
    snprintf(resources, sizeof resources, "file://%s/resources", argv[1]);
    void *library = dlopen(binary, RTLD_NOW | RTLD_LOCAL);
    Instantiate instantiate = library != NULL ? (Instantiate)dlsym(library, "fmi2Instantiate") : NULL;
    if (instantiate == NULL) {
        fprintf(stderr, "signal_host: cannot load fmi2Instantiate from %s\n", binary);
        return 2;
    }
    struct sigaction action;
    memset(&action, 0, sizeof action);
    action.sa_handler = on_alarm;
    action.sa_flags = 0; /* no SA_RESTART */
    sigemptyset(&action.sa_mask);
    long milliseconds = strtol(argv[4], NULL, 10);
    struct itimerval once = {{0, 0}, {milliseconds / 1000, (milliseconds % 1000) * 1000}};
    if (sigaction(SIGALRM, &action, NULL) != 0 || setitimer(ITIMER_REAL, &once, NULL) != 0) {
        perror("signal_host");
        return 2;
    }
    setvbuf(stdout, NULL, _IOLBF, 0);
    static const Callbacks callbacks = {logger, calloc, free, NULL, NULL};
    struct timespec start, end;
    clock_gettime(CLOCK_MONOTONIC, &start);
    void *instance = instantiate("signalled", 1, argv[3], resources, &callbacks, 0, 0);
    clock_gettime(CLOCK_MONOTONIC, &end);
    printf("signals %d\n", (int)signals);
    printf("result %s %.3f\n", instance != NULL ? "instance" : "null",
           (double)(end.tv_sec - start.tv_sec) + (double)(end.tv_nsec - start.tv_nsec) * 1e-9);
    printf("done\n");
    return 0;
}
