/* A hostile FMI 3.0 Co-Simulation host in C, without Python: the FMI 3.0 calling-sequence
 * equivalents of tests/hostile_host.c's cases (tests/slaves/test_fmi3.py compiles and runs it on
 * FMI 3.0 FMUs of ours), each on a fresh instance, printing what came back.
 *
 *   hostile_host3 DIR IDENTIFIER TOKEN REAL FIXED INPUT TIME
 *     DIR/binaries/x86_64-linux/IDENTIFIER.so is dlopen'ed (Windows, built with mingw-w64:
 *     DIR\binaries\x86_64-windows\IDENTIFIER.dll, LoadLibrary); REAL: a Float64 output's value
 *     reference; FIXED: a fixed Float64 parameter's ("-": none); INPUT: a Float64 input's ("-":
 *     none); TIME: the independent variable's.
 *
 * Output: "result CASE VALUE" (an fmi3Status number, "instance"/"null", "skip") and
 * "log CASE STATUS CATEGORY MESSAGE" for every logger call during the case.
 */
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef _WIN32
#include <windows.h>
#define dlopen(path, mode) ((void *)LoadLibraryExA(path, NULL, LOAD_WITH_ALTERED_SEARCH_PATH))
#define dlsym(library, name) ((void *)GetProcAddress((HMODULE)(library), name))
#define BINARY "%s\\binaries\\x86_64-windows\\%s.dll"
#define RESOURCES "%s\\resources"
static const char *dlerror(void) { return "LoadLibrary failed"; }
#else
#include <dlfcn.h>
#define BINARY "%s/binaries/x86_64-linux/%s.so"
#define RESOURCES "%s/resources"
#endif

typedef void *Instance;
typedef unsigned int VR;
typedef int Status;
typedef void (*Log)(void *, Status, const char *, const char *);

static struct {
    Instance (*instantiate)(const char *, const char *, const char *, bool, bool, bool, bool, const VR *, size_t,
                            void *, Log, void *);
    Instance (*instantiate_me)(const char *, const char *, const char *, bool, bool, void *, Log);
    void (*free_instance)(Instance);
    Status (*enter)(Instance, bool, double, double, bool, double);
    Status (*exit_init)(Instance);
    Status (*enter_event_mode)(Instance);
    Status (*terminate)(Instance);
    Status (*reset)(Instance);
    Status (*get_float64)(Instance, const VR *, size_t, double *, size_t);
    Status (*set_float64)(Instance, const VR *, size_t, const double *, size_t);
    Status (*get_int32)(Instance, const VR *, size_t, int *, size_t);
    Status (*get_float32)(Instance, const VR *, size_t, float *, size_t);
    Status (*do_step)(Instance, double, double, bool, bool *, bool *, bool *, double *);
    Status (*get_fmu_state)(Instance, void **);
} fmi;

static const char *current_case = "";
static char resources[4096], token[256];
static VR real_vr, fixed_vr, input_vr, time_vr;
static int has_fixed, has_input;

static void logger(void *env, Status status, const char *category, const char *message) {
    (void)env;
    printf("log %s %d %s ", current_case, status, category ? category : "-");
    for (const char *c = message; *c; c++) putchar(*c == '\n' ? ' ' : *c);
    printf("\n");
    fflush(stdout);
}

static Instance make(const char *name, const char *location) {
    return fmi.instantiate(name, token, location, false, true, false, false, NULL, 0, NULL, logger, NULL);
}

static Instance initialised(const char *name) {
    Instance c = make(name, resources);
    if (c == NULL) return NULL;
    fmi.enter(c, false, 0.0, 0.0, false, 0.0);
    fmi.exit_init(c);
    return c;
}

static Status step(Instance c, double t, double h) {
    bool event, terminate, early;
    double last;
    return fmi.do_step(c, t, h, true, &event, &terminate, &early, &last);
}

static void result(const char *name, Status status) {
    printf("result %s %d\n", name, status);
    fflush(stdout);
}

static void result_instance(const char *name, Instance c) {
    printf("result %s %s\n", name, c ? "instance" : "null");
    fflush(stdout);
}

#define CASE(name) for (int once = (current_case = name, 1); once; once = 0, current_case = "")

static void resource_case(const char *name, const char *location) {
    CASE(name) {
        Instance c = make("hostile", location);
        result_instance(name, c);
        if (c == NULL) continue;
        fmi.enter(c, false, 0.0, 0.0, false, 0.0);
        fmi.exit_init(c);
        char step_name[128];
        snprintf(step_name, sizeof step_name, "%s_step", name);
        result(step_name, step(c, 0.0, 0.1));
        fmi.free_instance(c);
    }
}

static void instantiation_cases(void) {
    char location[4200];
    resource_case("resource_null", NULL);
    resource_case("resource_empty", "");
    resource_case("resource_plain_path", resources);
    snprintf(location, sizeof location, "%s%c", resources, resources[0] == '/' ? '/' : '\\');
    resource_case("resource_trailing_separator", location);
    resource_case("resource_missing", "/nonexistent-greyfmu-folder/resources/");
    CASE("token_wrong") result_instance(current_case, fmi.instantiate("hostile", "{%s%n-not-the-token}", resources,
                                                                      false, true, false, false, NULL, 0, NULL, logger,
                                                                      NULL));
    CASE("token_null") result_instance(current_case, fmi.instantiate("hostile", NULL, resources, false, true, false,
                                                                     false, NULL, 0, NULL, logger, NULL));
    CASE("model_exchange") result_instance(current_case, fmi.instantiate_me("hostile", token, resources, false, true,
                                                                            NULL, logger));
    CASE("event_mode_used") result_instance(current_case, fmi.instantiate("hostile", token, resources, false, true,
                                                                          true, false, NULL, 0, NULL, logger, NULL));
    CASE("intermediate_variables") {
        VR required[1] = {real_vr};
        result_instance(current_case, fmi.instantiate("hostile", token, resources, false, true, false, false,
                                                      required, 1, NULL, logger, NULL));
    }
    CASE("name_null") result_instance(current_case, fmi.instantiate(NULL, token, resources, false, true, false, false,
                                                                    NULL, 0, NULL, logger, NULL));
    CASE("logger_null") {
        Instance c = fmi.instantiate("hostile", token, resources, false, true, false, false, NULL, 0, NULL, NULL, NULL);
        result_instance(current_case, c);
        if (c != NULL) {
            result("logger_null_step", step(c, 0.0, 0.1)); /* refused: said on stderr */
            fmi.free_instance(c);
        }
    }
}

static void state_cases(void) {
    double value;
    CASE("step_before_init") {
        Instance c = make("hostile", resources);
        result(current_case, step(c, 0.0, 0.1));
        fmi.free_instance(c);
    }
    CASE("step_in_initialization_mode") {
        Instance c = make("hostile", resources);
        fmi.enter(c, false, 0.0, 0.0, false, 0.0);
        result(current_case, step(c, 0.0, 0.1));
        fmi.free_instance(c);
    }
    CASE("step_after_terminate") {
        Instance c = initialised("hostile");
        fmi.terminate(c);
        result(current_case, step(c, 0.0, 0.1));
        fmi.free_instance(c);
    }
    CASE("exit_without_enter") {
        Instance c = make("hostile", resources);
        result(current_case, fmi.exit_init(c));
        fmi.free_instance(c);
    }
    CASE("enter_twice") {
        Instance c = make("hostile", resources);
        fmi.enter(c, false, 0.0, 0.0, false, 0.0);
        result(current_case, fmi.enter(c, false, 0.0, 0.0, false, 0.0));
        fmi.free_instance(c);
    }
    CASE("get_before_init") {
        Instance c = make("hostile", resources);
        result(current_case, fmi.get_float64(c, &real_vr, 1, &value, 1));
        fmi.free_instance(c);
    }
    CASE("terminate_before_init") {
        Instance c = make("hostile", resources);
        result(current_case, fmi.terminate(c));
        fmi.free_instance(c);
    }
    CASE("enter_event_mode") {
        Instance c = initialised("hostile");
        result(current_case, fmi.enter_event_mode(c));
        fmi.free_instance(c);
    }
    CASE("error_state_until_reset") {
        Instance c = make("hostile", resources);
        step(c, 0.0, 0.1); /* refused: the instance is in the error state */
        result("error_state_enter", fmi.enter(c, false, 0.0, 0.0, false, 0.0));
        result("error_state_get", fmi.get_float64(c, &real_vr, 1, &value, 1));
        result("error_state_reset", fmi.reset(c));
        fmi.enter(c, false, 0.0, 0.0, false, 0.0);
        fmi.exit_init(c);
        result("error_state_step_after_reset", step(c, 0.0, 0.1));
        fmi.free_instance(c);
    }
}

static void step_case(const char *name, double t, double h) {
    CASE(name) {
        Instance c = initialised("hostile");
        result(name, step(c, t, h));
        fmi.free_instance(c);
    }
}

static void argument_cases(void) {
    double value = 0.0;
    CASE("null_instance") {
        result("null_instance_step", step(NULL, 0.0, 0.1));
        result("null_instance_get", fmi.get_float64(NULL, &real_vr, 1, &value, 1));
        fmi.free_instance(NULL);
    }
    CASE("null_value_array") {
        Instance c = initialised("hostile");
        result(current_case, fmi.get_float64(c, &real_vr, 1, NULL, 1));
        fmi.free_instance(c);
    }
    CASE("null_vr_array") {
        Instance c = initialised("hostile");
        result(current_case, fmi.get_float64(c, NULL, 1, &value, 1));
        fmi.free_instance(c);
    }
    CASE("values_count") {
        Instance c = initialised("hostile");
        double values[4];
        result(current_case, fmi.get_float64(c, &real_vr, 1, values, 4));
        fmi.free_instance(c);
    }
    CASE("empty_arrays") {
        Instance c = initialised("hostile");
        result(current_case, fmi.get_float64(c, NULL, 0, NULL, 0));
        fmi.free_instance(c);
    }
    CASE("unknown_vr") {
        Instance c = initialised("hostile");
        VR unknown = 999999;
        result(current_case, fmi.get_float64(c, &unknown, 1, &value, 1));
        result("unknown_vr_then_get", fmi.get_float64(c, &real_vr, 1, &value, 1));
        fmi.free_instance(c);
    }
    CASE("wrong_type_vr") {
        Instance c = initialised("hostile");
        int integer;
        result(current_case, fmi.get_int32(c, &real_vr, 1, &integer, 1));
        fmi.free_instance(c);
    }
    CASE("no_such_type") {
        Instance c = initialised("hostile");
        float single;
        result(current_case, fmi.get_float32(c, &real_vr, 1, &single, 1));
        fmi.free_instance(c);
    }
    CASE("set_time") {
        Instance c = initialised("hostile");
        double later = 5.0;
        result(current_case, fmi.set_float64(c, &time_vr, 1, &later, 1));
        fmi.free_instance(c);
    }
    step_case("step_huge", 0.0, 1e300);
    step_case("step_negative", 0.0, -1.0);
    step_case("step_zero", 0.0, 0.0);
    step_case("step_nan", 0.0, NAN);
    step_case("time_nan", NAN, 0.1);
    CASE("step_null_outputs") {
        Instance c = initialised("hostile");
        bool event, terminate;
        result(current_case, fmi.do_step(c, 0.0, 0.1, true, &event, &terminate, NULL, NULL));
        fmi.free_instance(c);
    }
    CASE("step_outputs_written") {
        Instance c = initialised("hostile");
        bool event = true, terminate = true, early = true;
        double last = -1;
        result(current_case, fmi.do_step(c, 0.0, 0.1, true, &event, &terminate, &early, &last));
        printf("result step_outputs %d %d %d %.17g\n", event, terminate, early, last);
        fmi.free_instance(c);
    }
    CASE("step_not_from_the_last_end") {
        Instance c = initialised("hostile");
        step(c, 0.0, 0.1);
        result(current_case, step(c, 5.0, 0.1));
        fmi.free_instance(c);
    }
    CASE("step_past_stop_time") {
        Instance c = make("hostile", resources);
        fmi.enter(c, false, 0.0, 0.0, true, 1.0);
        fmi.exit_init(c);
        result("step_to_stop_time", step(c, 0.0, 1.0 - 1e-14));
        result(current_case, step(c, 1.0, 0.5));
        fmi.free_instance(c);
    }
    CASE("set_fixed_after_init") {
        if (!has_fixed) {
            printf("result %s skip\n", current_case);
            continue;
        }
        Instance c = initialised("hostile");
        double before = 0, after = 0, changed;
        fmi.get_float64(c, &fixed_vr, 1, &before, 1);
        changed = before + 1.0;
        result(current_case, fmi.set_float64(c, &fixed_vr, 1, &changed, 1));
        fmi.get_float64(c, &fixed_vr, 1, &after, 1);
        printf("result set_fixed_unchanged %d\n", before == after);
        fmi.free_instance(c);
    }
    CASE("null_fmu_state") {
        Instance c = initialised("hostile");
        result(current_case, fmi.get_fmu_state(c, NULL));
        fmi.free_instance(c);
    }
    CASE("start_time") { /* the start time reaches the slave: time reads it before the first step */
        Instance c = make("hostile", resources);
        fmi.enter(c, false, 0.0, 7.5, false, 0.0);
        fmi.exit_init(c);
        double now = -1;
        result(current_case, fmi.get_float64(c, &time_vr, 1, &now, 1));
        printf("result start_time_value %.17g\n", now);
        result("start_time_step", step(c, 7.5, 0.1));
        fmi.free_instance(c);
    }
}

static void format_cases(void) {
    CASE("format_guard") {
        Instance c = make("%s%n%s%n", resources);
        result(current_case, step(c, 0.0, 0.1));
        fmi.free_instance(c);
    }
    CASE("format_slave") {
        if (!has_input) {
            printf("result %s skip\n", current_case);
            continue;
        }
        Instance c = initialised("%s%n%s%n");
        double nan = NAN;
        fmi.set_float64(c, &input_vr, 1, &nan, 1);
        result(current_case, step(c, 0.0, 0.1));
        fmi.free_instance(c);
    }
}

static void *need(void *library, const char *name) {
    void *symbol = dlsym(library, name);
    if (symbol == NULL) {
        fprintf(stderr, "hostile_host3: the FMU has no %s\n", name);
        exit(2);
    }
    return symbol;
}

int main(int argc, char **argv) {
    if (argc != 8) {
        fprintf(stderr, "usage: hostile_host3 DIR IDENTIFIER TOKEN REAL FIXED INPUT TIME\n");
        return 2;
    }
    char binary[4096];
    snprintf(binary, sizeof binary, BINARY, argv[1], argv[2]);
    snprintf(resources, sizeof resources, RESOURCES, argv[1]);
    snprintf(token, sizeof token, "%s", argv[3]);
    real_vr = (VR)strtoul(argv[4], NULL, 10);
    has_fixed = strcmp(argv[5], "-") != 0;
    fixed_vr = (VR)strtoul(argv[5], NULL, 10);
    has_input = strcmp(argv[6], "-") != 0;
    input_vr = (VR)strtoul(argv[6], NULL, 10);
    time_vr = (VR)strtoul(argv[7], NULL, 10);
    void *library = dlopen(binary, RTLD_NOW | RTLD_LOCAL);
    if (library == NULL) {
        fprintf(stderr, "hostile_host3: %s\n", dlerror());
        return 2;
    }
    *(void **)&fmi.instantiate = need(library, "fmi3InstantiateCoSimulation");
    *(void **)&fmi.instantiate_me = need(library, "fmi3InstantiateModelExchange");
    *(void **)&fmi.free_instance = need(library, "fmi3FreeInstance");
    *(void **)&fmi.enter = need(library, "fmi3EnterInitializationMode");
    *(void **)&fmi.exit_init = need(library, "fmi3ExitInitializationMode");
    *(void **)&fmi.enter_event_mode = need(library, "fmi3EnterEventMode");
    *(void **)&fmi.terminate = need(library, "fmi3Terminate");
    *(void **)&fmi.reset = need(library, "fmi3Reset");
    *(void **)&fmi.get_float64 = need(library, "fmi3GetFloat64");
    *(void **)&fmi.set_float64 = need(library, "fmi3SetFloat64");
    *(void **)&fmi.get_int32 = need(library, "fmi3GetInt32");
    *(void **)&fmi.get_float32 = need(library, "fmi3GetFloat32");
    *(void **)&fmi.do_step = need(library, "fmi3DoStep");
    *(void **)&fmi.get_fmu_state = need(library, "fmi3GetFMUState");
    instantiation_cases();
    state_cases();
    argument_cases();
    format_cases();
    printf("done\n");
    return 0;
}
