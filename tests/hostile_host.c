/* A hostile FMI 2.0 Co-Simulation host in C: it misuses an FMU in every way tests/slaves/
 * test_hostile_host.py checks (compiled there with the system compiler), each case on a fresh
 * instance, and prints what came back.
 *
 *   hostile_host DIR IDENTIFIER GUID REAL FIXED FIXED_TYPE INPUT TUNABLE
 *     DIR/binaries/linux64/IDENTIFIER.so is dlopen'ed (Windows, built with mingw-w64:
 *     DIR\binaries\win64\IDENTIFIER.dll, LoadLibrary); REAL: the value reference of a Real
 *     variable; FIXED, FIXED_TYPE (R, I or B): a fixed parameter, INPUT: a Real input,
 *     TUNABLE: a Real tunable parameter ("-": none, the cases needing them are skipped).
 *
 * Output, one line each: "result CASE STATUS" (an fmi2Status number, "instance" or "null" for
 * fmi2Instantiate, "skip") and "log CASE STATUS CATEGORY MESSAGE" for every logger call during
 * the case.  The logger formats its arguments as a plain C host does (vsnprintf of the format):
 * an FMU passing a message as the format with %n in it would crash this host.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef _WIN32
#include <windows.h>
#define dlopen(path, mode) ((void *)LoadLibraryExA(path, NULL, LOAD_WITH_ALTERED_SEARCH_PATH))
#define dlsym(library, name) ((void *)GetProcAddress((HMODULE)(library), name))
#define BINARY "%s\\binaries\\win64\\%s.dll"
#define RESOURCES "%s\\resources"
static const char *dlerror(void) { return "LoadLibrary failed"; }
#else
#include <dlfcn.h>
#define BINARY "%s/binaries/linux64/%s.so"
#define RESOURCES "%s/resources"
#endif

typedef void *fmi2Component;
typedef void *fmi2FMUstate;
typedef unsigned int fmi2ValueReference;
typedef int fmi2Status;
typedef void (*Logger)(void *, const char *, fmi2Status, const char *, const char *, ...);
typedef struct {
    Logger logger;
    void *(*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void *);
    void (*stepFinished)(void *, fmi2Status);
    void *componentEnvironment;
} Callbacks;

static struct {
    fmi2Component (*instantiate)(const char *, int, const char *, const char *, const Callbacks *, int, int);
    void (*free_instance)(fmi2Component);
    fmi2Status (*setup)(fmi2Component, int, double, double, int, double);
    fmi2Status (*enter)(fmi2Component);
    fmi2Status (*exit_init)(fmi2Component);
    fmi2Status (*terminate)(fmi2Component);
    fmi2Status (*reset)(fmi2Component);
    fmi2Status (*get_real)(fmi2Component, const fmi2ValueReference *, size_t, double *);
    fmi2Status (*get_integer)(fmi2Component, const fmi2ValueReference *, size_t, int *);
    fmi2Status (*get_boolean)(fmi2Component, const fmi2ValueReference *, size_t, int *);
    fmi2Status (*set_real)(fmi2Component, const fmi2ValueReference *, size_t, const double *);
    fmi2Status (*set_integer)(fmi2Component, const fmi2ValueReference *, size_t, const int *);
    fmi2Status (*set_boolean)(fmi2Component, const fmi2ValueReference *, size_t, const int *);
    fmi2Status (*do_step)(fmi2Component, double, double, int);
    fmi2Status (*cancel_step)(fmi2Component);
    fmi2Status (*get_real_status)(fmi2Component, int, double *);
    fmi2Status (*get_fmu_state)(fmi2Component, fmi2FMUstate *);
} fmi;

static const char *current_case = "";
static char resources[4096], guid[256];
static char uri_path[4200]; /* resources as a URI path: /C:/... on Windows */
static fmi2ValueReference real_vr, fixed_vr, input_vr, tunable_vr;
static char fixed_type;
static int has_fixed, has_input, has_tunable;

static void logger(void *env, const char *name, fmi2Status status, const char *category, const char *format, ...) {
    (void)env;
    (void)name;
    char message[8192];
    va_list args;
    va_start(args, format);
    vsnprintf(message, sizeof message, format, args);
    va_end(args);
    for (char *c = message; *c; c++)
        if (*c == '\n') *c = ' ';
    printf("log %s %d %s %s\n", current_case, status, category ? category : "-", message);
    fflush(stdout);
}

static Callbacks callbacks = {logger, calloc, free, NULL, NULL};

static fmi2Component make(const char *name, const char *location) {
    return fmi.instantiate(name, 1, guid, location, &callbacks, 0, 1);
}

static fmi2Component initialised(const char *name) {
    fmi2Component c = make(name, resources);
    if (c == NULL) return NULL;
    fmi.setup(c, 0, 0.0, 0.0, 0, 0.0);
    fmi.enter(c);
    fmi.exit_init(c);
    return c;
}

static void result(const char *name, fmi2Status status) {
    printf("result %s %d\n", name, status);
    fflush(stdout);
}

static void result_instance(const char *name, fmi2Component c) {
    printf("result %s %s\n", name, c ? "instance" : "null");
    fflush(stdout);
}

#define CASE(name) for (int once = (current_case = name, 1); once; once = 0, current_case = "")

/* An instantiation with this resource location, then one step: the instance and the status. */
static void resource_case(const char *name, const char *location) {
    CASE(name) {
        fmi2Component c = make("hostile", location);
        result_instance(name, c);
        if (c == NULL) continue;
        fmi.setup(c, 0, 0.0, 0.0, 0, 0.0);
        fmi.enter(c);
        fmi.exit_init(c);
        char step_name[128];
        snprintf(step_name, sizeof step_name, "%s_step", name);
        result(step_name, fmi.do_step(c, 0.0, 0.1, 1));
        fmi.free_instance(c);
    }
}

/* "file://" + the path with every byte but '/' percent-encoded. */
static void percent_encoded(const char *path, char *uri, size_t size) {
    size_t used = (size_t)snprintf(uri, size, "file://");
    for (const char *c = path; *c && used + 4 < size; c++)
        used += *c == '/' ? (size_t)snprintf(uri + used, size - used, "/")
                          : (size_t)snprintf(uri + used, size - used, "%%%02X", (unsigned char)*c);
}

static void instantiation_cases(void) {
    char uri[8192];
    resource_case("resource_null", NULL);
    resource_case("resource_empty", "");
    snprintf(uri, sizeof uri, "file:%s", uri_path);
    resource_case("resource_file_one_slash", uri);
    snprintf(uri, sizeof uri, "file://%s", uri_path);
    resource_case("resource_file_three_slashes", uri);
    snprintf(uri, sizeof uri, "file://localhost%s", uri_path);
    resource_case("resource_file_localhost", uri);
    snprintf(uri, sizeof uri, "file://%s/", uri_path);
    resource_case("resource_trailing_slash", uri);
    percent_encoded(uri_path, uri, sizeof uri);
    resource_case("resource_percent_encoded", uri);
    resource_case("resource_plain_path", resources);
    resource_case("resource_missing", "file:///nonexistent-greyfmu-folder/resources");
    resource_case("resource_other_host", "file://elsewhere/tmp/resources");
    resource_case("resource_http", "http://example.com/resources");
    resource_case("resource_bad_percent", "file:///tmp/%zz");
    CASE("guid_wrong") result_instance(current_case, fmi.instantiate("hostile", 1, "{%s%n-not-the-guid}", resources,
                                                                     &callbacks, 0, 1));
    CASE("guid_null") result_instance(current_case, fmi.instantiate("hostile", 1, NULL, resources, &callbacks, 0, 1));
    CASE("model_exchange") result_instance(current_case, fmi.instantiate("hostile", 0, guid, resources, &callbacks, 0, 1));
    CASE("callbacks_null") result_instance(current_case, fmi.instantiate("hostile", 1, guid, resources, NULL, 0, 1));
    CASE("logger_null") {
        Callbacks no_logger = {NULL, calloc, free, NULL, NULL};
        result_instance(current_case, fmi.instantiate("hostile", 1, guid, resources, &no_logger, 0, 1));
    }
    CASE("name_null") result_instance(current_case, fmi.instantiate(NULL, 1, guid, resources, &callbacks, 0, 1));
}

static void state_cases(void) {
    double value;
    CASE("step_before_init") {
        fmi2Component c = make("hostile", resources);
        result(current_case, fmi.do_step(c, 0.0, 0.1, 1));
        fmi.free_instance(c);
    }
    CASE("step_in_initialization_mode") {
        fmi2Component c = make("hostile", resources);
        fmi.enter(c);
        result(current_case, fmi.do_step(c, 0.0, 0.1, 1));
        fmi.free_instance(c);
    }
    CASE("step_after_terminate") {
        fmi2Component c = initialised("hostile");
        fmi.terminate(c);
        result(current_case, fmi.do_step(c, 0.0, 0.1, 1));
        fmi.free_instance(c);
    }
    CASE("exit_without_enter") {
        fmi2Component c = make("hostile", resources);
        result(current_case, fmi.exit_init(c));
        fmi.free_instance(c);
    }
    CASE("enter_twice") {
        fmi2Component c = make("hostile", resources);
        fmi.enter(c);
        result(current_case, fmi.enter(c));
        fmi.free_instance(c);
    }
    CASE("setup_after_init") {
        fmi2Component c = initialised("hostile");
        result(current_case, fmi.setup(c, 0, 0.0, 0.0, 0, 0.0));
        fmi.free_instance(c);
    }
    CASE("get_before_init") {
        fmi2Component c = make("hostile", resources);
        result(current_case, fmi.get_real(c, &real_vr, 1, &value));
        fmi.free_instance(c);
    }
    CASE("terminate_before_init") {
        fmi2Component c = make("hostile", resources);
        result(current_case, fmi.terminate(c));
        fmi.free_instance(c);
    }
    CASE("cancel_step") {
        fmi2Component c = initialised("hostile");
        result(current_case, fmi.cancel_step(c));
        fmi.free_instance(c);
    }
    CASE("error_state_until_reset") {
        fmi2Component c = make("hostile", resources);
        fmi.do_step(c, 0.0, 0.1, 1); /* refused: the instance is in the error state */
        result("error_state_enter", fmi.enter(c));
        result("error_state_get", fmi.get_real(c, &real_vr, 1, &value));
        result("error_state_reset", fmi.reset(c));
        fmi.setup(c, 0, 0.0, 0.0, 0, 0.0);
        fmi.enter(c);
        fmi.exit_init(c);
        result("error_state_step_after_reset", fmi.do_step(c, 0.0, 0.1, 1));
        fmi.free_instance(c);
    }
}

static void step_case(const char *name, double t, double h) {
    CASE(name) {
        fmi2Component c = initialised("hostile");
        result(name, fmi.do_step(c, t, h, 1));
        fmi.free_instance(c);
    }
}

static void argument_cases(void) {
    double value = 0.0;
    CASE("null_instance") {
        result("null_instance_step", fmi.do_step(NULL, 0.0, 0.1, 1));
        result("null_instance_get", fmi.get_real(NULL, &real_vr, 1, &value));
        result("null_instance_set", fmi.set_real(NULL, &real_vr, 1, &value));
        result("null_instance_terminate", fmi.terminate(NULL));
        fmi.free_instance(NULL);
    }
    CASE("null_value_array") {
        fmi2Component c = initialised("hostile");
        result(current_case, fmi.get_real(c, &real_vr, 1, NULL));
        fmi.free_instance(c);
    }
    CASE("null_vr_array") {
        fmi2Component c = initialised("hostile");
        result(current_case, fmi.get_real(c, NULL, 1, &value));
        fmi.free_instance(c);
    }
    CASE("null_set_array") {
        fmi2Component c = make("hostile", resources);
        result(current_case, fmi.set_real(c, &real_vr, 1, NULL));
        fmi.free_instance(c);
    }
    CASE("empty_arrays") {
        fmi2Component c = initialised("hostile");
        result(current_case, fmi.get_real(c, NULL, 0, NULL));
        fmi.free_instance(c);
    }
    CASE("unknown_vr") {
        fmi2Component c = initialised("hostile");
        fmi2ValueReference unknown = 999999;
        result(current_case, fmi.get_real(c, &unknown, 1, &value));
        result("unknown_vr_then_get", fmi.get_real(c, &real_vr, 1, &value));
        fmi.free_instance(c);
    }
    CASE("wrong_type_vr") {
        fmi2Component c = initialised("hostile");
        int integer;
        result(current_case, fmi.get_integer(c, &real_vr, 1, &integer));
        fmi.free_instance(c);
    }
    step_case("step_huge", 0.0, 1e300);
    step_case("step_negative", 0.0, -1.0);
    step_case("step_zero", 0.0, 0.0);
    step_case("step_nan", 0.0, NAN);
    step_case("step_infinite", 0.0, INFINITY);
    step_case("time_nan", NAN, 0.1);
    CASE("step_not_from_the_last_end") {
        fmi2Component c = initialised("hostile");
        fmi.do_step(c, 0.0, 0.1, 1);
        result(current_case, fmi.do_step(c, 5.0, 0.1, 1));
        fmi.free_instance(c);
    }
    CASE("step_past_stop_time") {
        fmi2Component c = make("hostile", resources);
        fmi.setup(c, 0, 0.0, 0.0, 1, 1.0);
        fmi.enter(c);
        fmi.exit_init(c);
        result("step_to_stop_time", fmi.do_step(c, 0.0, 1.0 - 1e-14, 1));
        result(current_case, fmi.do_step(c, 1.0, 0.5, 1));
        fmi.free_instance(c);
    }
    CASE("set_fixed_after_init") {
        if (!has_fixed) {
            printf("result %s skip\n", current_case);
            continue;
        }
        fmi2Component c = initialised("hostile");
        double before = 0, after = 0, changed;
        int ibefore = 0, iafter = 0, ichanged;
        if (fixed_type == 'R') {
            fmi.get_real(c, &fixed_vr, 1, &before);
            changed = before + 1.0;
            result(current_case, fmi.set_real(c, &fixed_vr, 1, &changed));
            fmi.get_real(c, &fixed_vr, 1, &after);
        } else {
            (fixed_type == 'I' ? fmi.get_integer : fmi.get_boolean)(c, &fixed_vr, 1, &ibefore);
            ichanged = fixed_type == 'I' ? ibefore + 1 : !ibefore;
            result(current_case, (fixed_type == 'I' ? fmi.set_integer : fmi.set_boolean)(c, &fixed_vr, 1, &ichanged));
            (fixed_type == 'I' ? fmi.get_integer : fmi.get_boolean)(c, &fixed_vr, 1, &iafter);
        }
        printf("result set_fixed_unchanged %d\n", before == after && ibefore == iafter);
        fmi.free_instance(c);
    }
    CASE("set_tunable_after_init") {
        if (!has_tunable) {
            printf("result %s skip\n", current_case);
            continue;
        }
        fmi2Component c = initialised("hostile");
        double before = 0, after = 0, changed;
        fmi.get_real(c, &tunable_vr, 1, &before);
        changed = before * 1.5 + 0.25;
        result(current_case, fmi.set_real(c, &tunable_vr, 1, &changed));
        fmi.get_real(c, &tunable_vr, 1, &after);
        printf("result set_tunable_changed %d\n", after == changed);
        fmi.free_instance(c);
    }
    CASE("null_status_value") {
        fmi2Component c = initialised("hostile");
        fmi.do_step(c, 0.0, 0.1, 1);
        result(current_case, fmi.get_real_status(c, 2, NULL));
        fmi.free_instance(c);
    }
    CASE("null_fmu_state") {
        fmi2Component c = initialised("hostile");
        result(current_case, fmi.get_fmu_state(c, NULL));
        fmi.free_instance(c);
    }
}

static void format_cases(void) {
    CASE("format_guard") {
        fmi2Component c = make("%s%n%s%n", resources);
        result(current_case, fmi.do_step(c, 0.0, 0.1, 1));
        fmi.free_instance(c);
    }
    CASE("format_slave") {
        if (!has_input) {
            printf("result %s skip\n", current_case);
            continue;
        }
        fmi2Component c = initialised("%s%n%s%n");
        double nan = NAN;
        fmi.set_real(c, &input_vr, 1, &nan);
        result(current_case, fmi.do_step(c, 0.0, 0.1, 1));
        fmi.free_instance(c);
    }
}

static void *need(void *library, const char *name) {
    void *symbol = dlsym(library, name);
    if (symbol == NULL) {
        fprintf(stderr, "hostile_host: the FMU has no %s\n", name);
        exit(2);
    }
    return symbol;
}

int main(int argc, char **argv) {
    if (argc != 9) {
        fprintf(stderr, "usage: hostile_host DIR IDENTIFIER GUID REAL FIXED FIXED_TYPE INPUT TUNABLE\n");
        return 2;
    }
    char binary[4096];
    snprintf(binary, sizeof binary, BINARY, argv[1], argv[2]);
    snprintf(resources, sizeof resources, RESOURCES, argv[1]);
    snprintf(uri_path, sizeof uri_path, "%s%s", resources[0] == '/' ? "" : "/", resources);
    for (char *c = uri_path; *c; c++)
        if (*c == '\\') *c = '/';
    snprintf(guid, sizeof guid, "%s", argv[3]);
    real_vr = (fmi2ValueReference)strtoul(argv[4], NULL, 10);
    has_fixed = strcmp(argv[5], "-") != 0;
    fixed_vr = (fmi2ValueReference)strtoul(argv[5], NULL, 10);
    fixed_type = argv[6][0];
    has_input = strcmp(argv[7], "-") != 0;
    input_vr = (fmi2ValueReference)strtoul(argv[7], NULL, 10);
    has_tunable = strcmp(argv[8], "-") != 0;
    tunable_vr = (fmi2ValueReference)strtoul(argv[8], NULL, 10);
    void *library = dlopen(binary, RTLD_NOW | RTLD_LOCAL);
    if (library == NULL) {
        fprintf(stderr, "hostile_host: %s\n", dlerror());
        return 2;
    }
    *(void **)&fmi.instantiate = need(library, "fmi2Instantiate");
    *(void **)&fmi.free_instance = need(library, "fmi2FreeInstance");
    *(void **)&fmi.setup = need(library, "fmi2SetupExperiment");
    *(void **)&fmi.enter = need(library, "fmi2EnterInitializationMode");
    *(void **)&fmi.exit_init = need(library, "fmi2ExitInitializationMode");
    *(void **)&fmi.terminate = need(library, "fmi2Terminate");
    *(void **)&fmi.reset = need(library, "fmi2Reset");
    *(void **)&fmi.get_real = need(library, "fmi2GetReal");
    *(void **)&fmi.get_integer = need(library, "fmi2GetInteger");
    *(void **)&fmi.get_boolean = need(library, "fmi2GetBoolean");
    *(void **)&fmi.set_real = need(library, "fmi2SetReal");
    *(void **)&fmi.set_integer = need(library, "fmi2SetInteger");
    *(void **)&fmi.set_boolean = need(library, "fmi2SetBoolean");
    *(void **)&fmi.do_step = need(library, "fmi2DoStep");
    *(void **)&fmi.cancel_step = need(library, "fmi2CancelStep");
    *(void **)&fmi.get_real_status = need(library, "fmi2GetRealStatus");
    *(void **)&fmi.get_fmu_state = need(library, "fmi2GetFMUstate");
    instantiation_cases();
    state_cases();
    argument_cases();
    format_cases();
    printf("done\n");
    return 0;
}
