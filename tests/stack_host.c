/* A C host that calls an FMU's fmi2Instantiate on worker threads with small stacks, as a host
 * with a thread pool may (compiled by tests/slaves/test_loader_stack.py with the system compiler).
 *
 *   stack_host DIR IDENTIFIER GUID KB...
 *     DIR/binaries/linux64/IDENTIFIER.so is dlopen'ed; for each KB, in order, a thread with a
 *     stack of KB KiB (below it an inaccessible guard page: an overflow is a SIGSEGV, never a
 *     silent overwrite) instantiates the FMU, steps it once and frees it.  The first such call
 *     in a process without Python starts Python (greyfmu/loader/fmi2_loader.c).
 *
 * Output, one line each: "call N KB STATUS USED" (STATUS: "instance", "null" or the fmi2DoStep
 * status; USED: the bytes of the thread's stack written, found by filling the stack with a
 * pattern first and looking for the lowest byte changed), "log ..." for each logger call,
 * then "done".
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <unistd.h>

typedef void *fmi2Component;
typedef int fmi2Status;
typedef void (*Logger)(void *, const char *, fmi2Status, const char *, const char *, ...);
typedef struct {
    Logger logger;
    void *(*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void *);
    void (*stepFinished)(void *, fmi2Status);
    void *componentEnvironment;
} Callbacks;

enum { PATTERN = 0xA5 };

static struct {
    fmi2Component (*instantiate)(const char *, int, const char *, const char *, const Callbacks *, int, int);
    void (*free_instance)(fmi2Component);
    fmi2Status (*setup)(fmi2Component, int, double, double, int, double);
    fmi2Status (*enter)(fmi2Component);
    fmi2Status (*exit_init)(fmi2Component);
    fmi2Status (*do_step)(fmi2Component, double, double, int);
} fmi;

static char resources[4096], guid[256];

static void logger(void *env, const char *name, fmi2Status status, const char *category, const char *format, ...) {
    (void)env;
    (void)name;
    char message[8192];
    va_list args;
    va_start(args, format);
    vsnprintf(message, sizeof message, format, args);
    va_end(args);
    printf("log %d %s %s\n", status, category, message);
}

static void *call(void *result) {
    static const Callbacks callbacks = {logger, calloc, free, NULL, NULL};
    fmi2Component c = fmi.instantiate("stack", 1, guid, resources, &callbacks, 0, 0);
    if (c == NULL) {
        snprintf(result, 32, "null");
        return NULL;
    }
    fmi2Status status = fmi.setup(c, 0, 0.0, 0.0, 0, 0.0);
    if (status == 0) status = fmi.enter(c);
    if (status == 0) status = fmi.exit_init(c);
    if (status == 0) status = fmi.do_step(c, 0.0, 1e-3, 1);
    snprintf(result, 32, status == 0 ? "instance" : "%d", status);
    fmi.free_instance(c);
    return NULL;
}

/* One call on a thread with a painted stack of `kb` KiB; the bytes of it written. */
static size_t on_small_stack(size_t kb, char *result) {
    size_t page = (size_t)sysconf(_SC_PAGESIZE), size = kb * 1024;
    unsigned char *region = mmap(NULL, size + page, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (region == MAP_FAILED || mprotect(region, page, PROT_NONE) != 0) {
        perror("stack_host: mmap");
        exit(2);
    }
    memset(region + page, PATTERN, size);
    pthread_attr_t attributes;
    pthread_t thread;
    if (pthread_attr_init(&attributes) != 0 || pthread_attr_setstack(&attributes, region + page, size) != 0 ||
        pthread_create(&thread, &attributes, call, result) != 0 || pthread_join(thread, NULL) != 0) {
        fprintf(stderr, "stack_host: cannot run a thread with a %zu KiB stack\n", kb);
        exit(2);
    }
    pthread_attr_destroy(&attributes);
    size_t untouched = 0;
    while (untouched < size && region[page + untouched] == PATTERN) untouched++;
    munmap(region, size + page);
    return size - untouched;
}

int main(int argc, char **argv) {
    if (argc < 5) {
        fprintf(stderr, "usage: stack_host DIR IDENTIFIER GUID KB...\n");
        return 2;
    }
    char binary[4200];
    snprintf(binary, sizeof binary, "%s/binaries/linux64/%s.so", argv[1], argv[2]);
    snprintf(resources, sizeof resources, "file://%s/resources", argv[1]);
    snprintf(guid, sizeof guid, "%s", argv[3]);
    void *library = dlopen(binary, RTLD_NOW | RTLD_LOCAL);
    if (library == NULL) {
        fprintf(stderr, "stack_host: %s\n", dlerror());
        return 2;
    }
    *(void **)&fmi.instantiate = dlsym(library, "fmi2Instantiate");
    *(void **)&fmi.free_instance = dlsym(library, "fmi2FreeInstance");
    *(void **)&fmi.setup = dlsym(library, "fmi2SetupExperiment");
    *(void **)&fmi.enter = dlsym(library, "fmi2EnterInitializationMode");
    *(void **)&fmi.exit_init = dlsym(library, "fmi2ExitInitializationMode");
    *(void **)&fmi.do_step = dlsym(library, "fmi2DoStep");
    if (!fmi.instantiate || !fmi.free_instance || !fmi.setup || !fmi.enter || !fmi.exit_init || !fmi.do_step) {
        fprintf(stderr, "stack_host: %s lacks an fmi2 function\n", binary);
        return 2;
    }
    setvbuf(stdout, NULL, _IOLBF, 0);
    for (int i = 4; i < argc; i++) {
        char result[32];
        size_t kb = strtoul(argv[i], NULL, 10), used = on_small_stack(kb, result);
        printf("call %d %zu %s %zu\n", i - 4, kb, result, used);
    }
    printf("done\n");
    return 0;
}
