/* greyfmu drop-in loader for FMI 3.0: the binary of every greyfmu FMI 3.0 Co-Simulation FMU
 * (binaries/x86_64-linux/<modelIdentifier>.so, binaries/x86_64-windows/<modelIdentifier>.dll;
 * greyfmu.fmi3 builds them).
 *
 * The FMI 2.0 loader's guarantees (fmi2_loader.c's top comment), with its code: the same Python
 * search and one start per process (python.h, process.c, platform.h), the same guard (guard.h)
 * and FMU states (states.h).  It forwards to pythonfmu3 0.3.4's library, shipped next to it as
 * pythonfmu3-export.so (.dll), which, like pythonfmu 0.7.0's, does not link libpython, answers
 * every Python exception with fmi3Fatal after releasing the instance's objects, and frees its
 * static state twice at exit; the slave's class is the FMI 3.0 class of the FMU's FMI 2.0 slave
 * (fmus/fmi3/_slave3.py).
 *
 * What FMI 3.0 changes in the guard:
 *  - the state machine of a Co-Simulation FMU without event mode (FMI 3.0 §4.2): instantiated,
 *    initializationMode, stepMode, stepDiscarded, terminated (and the error and fatal states);
 *    fmi3EnterEventMode, fmi3EnterStepMode, configuration mode, clocks, Model Exchange and
 *    Scheduled Execution functions are refused with a line saying why (this FMU declares none of
 *    them), fmi3InstantiateModelExchange and fmi3InstantiateScheduledExecution return NULL;
 *  - fmi3InstantiateCoSimulation refuses eventModeUsed and required intermediate variables
 *    (hasEventMode and providesIntermediateUpdate are false); its logMessage may be NULL (the
 *    guard's lines then go to stderr); fmuResourceLocation is resourcePath, a folder path;
 *  - every fmi3Get/Set checks nValues: the FMU's variables are scalars, so nValues = nvr; the
 *    types it has none of (Float32, Int8, ..., Binary, Clock) refuse any value reference;
 *  - fmi3EnterInitializationMode checks startTime/stopTime as fmi2SetupExperiment does and gives
 *    the start time to the slave by setting the independent variable `time` (pythonfmu3 drops
 *    it), so the slave builds its objects for the same start as its FMI 2.0 sibling;
 *  - fmi3DoStep refuses NULL output pointers and writes false to eventHandlingNeeded and
 *    earlyReturn (pythonfmu3 leaves them unwritten) and terminateSimulation before forwarding;
 *  - the host's logger takes the message as data (fmi3LogMessageCallback has no format).
 */
#define _GNU_SOURCE
#include "platform.h"
#include "python.h"

/* ---- FMI 3.0 types (fmi3PlatformTypes.h, fmi3FunctionTypes.h) ---- */
typedef void *fmi3Instance;
typedef void *fmi3InstanceEnvironment;
typedef void *fmi3FMUState;
typedef unsigned int fmi3ValueReference;
typedef float fmi3Float32;
typedef double fmi3Float64;
typedef int8_t fmi3Int8;
typedef uint8_t fmi3UInt8;
typedef int16_t fmi3Int16;
typedef uint16_t fmi3UInt16;
typedef int32_t fmi3Int32;
typedef uint32_t fmi3UInt32;
typedef int64_t fmi3Int64;
typedef uint64_t fmi3UInt64;
typedef _Bool fmi3Boolean;
typedef const char *fmi3String;
typedef uint8_t fmi3Byte;
typedef const fmi3Byte *fmi3Binary;
typedef _Bool fmi3Clock;
typedef enum { fmi3OK, fmi3Warning, fmi3Discard, fmi3Error, fmi3Fatal } fmi3Status;
typedef enum { fmi3IntervalNotYetKnown, fmi3IntervalUnchanged, fmi3IntervalChanged } fmi3IntervalQualifier;
typedef enum { fmi3Independent, fmi3Constant, fmi3Fixed, fmi3Tunable, fmi3Discrete, fmi3Dependent } fmi3DependencyKind;
typedef void (*fmi3LogMessageCallback)(fmi3InstanceEnvironment, fmi3Status, fmi3String, fmi3String);
typedef void (*fmi3IntermediateUpdateCallback)(fmi3InstanceEnvironment, fmi3Float64, fmi3Boolean, fmi3Boolean,
                                               fmi3Boolean, fmi3Boolean, fmi3Boolean *, fmi3Float64 *);

static void *pythonfmu_library;
static int live_instances;
static int exit_handler_registered;

/* ---- forwarding: one pointer per fmi3 function of pythonfmu3-export.so the loader calls ---- */
#define FMI3_FUNCTIONS(X)                                                                                          \
    X(fmi3InstantiateCoSimulation)                                                                                 \
    X(fmi3FreeInstance)                                                                                            \
    X(fmi3EnterInitializationMode)                                                                                 \
    X(fmi3ExitInitializationMode)                                                                                  \
    X(fmi3Terminate)                                                                                               \
    X(fmi3Reset)                                                                                                   \
    X(fmi3GetFloat64)                                                                                              \
    X(fmi3GetInt32)                                                                                                \
    X(fmi3GetInt64)                                                                                                \
    X(fmi3GetBoolean)                                                                                              \
    X(fmi3GetString)                                                                                               \
    X(fmi3SetFloat64)                                                                                              \
    X(fmi3SetInt32)                                                                                                \
    X(fmi3SetInt64)                                                                                                \
    X(fmi3SetBoolean)                                                                                              \
    X(fmi3SetString)                                                                                               \
    X(fmi3GetFMUState)                                                                                             \
    X(fmi3SetFMUState)                                                                                             \
    X(fmi3DoStep)

#define DECLARE_POINTER(name) static void *real_##name;
FMI3_FUNCTIONS(DECLARE_POINTER)
static void (*real_finalizePythonInterpreter)(void);

static void release_pythonfmu_state(void) {
    if (real_finalizePythonInterpreter != NULL) real_finalizePythonInterpreter();
}

static int load_pythonfmu(const char *root, char *problem, size_t size) {
    char library[PATH_MAX + 64];
    snprintf(library, sizeof library, "%s%cbinaries%c" PLATFORM_FOLDER3 "%cpythonfmu3-export" LIBRARY_SUFFIX, root,
             SEPARATOR, SEPARATOR, SEPARATOR);
    void *handle = library_open(library, 0, problem, size);
    if (handle == NULL) return 0;
#define LOOK_UP(name)                                                                                              \
    if ((*(void **)&real_##name = library_symbol(handle, #name)) == NULL) {                                       \
        append(problem, size, "%s has no %s", library, #name);                                                     \
        return 0;                                                                                                  \
    }
    FMI3_FUNCTIONS(LOOK_UP)
    LOOK_UP(finalizePythonInterpreter)
#undef LOOK_UP
    pythonfmu_library = handle;
    if (!exit_handler_registered) {
        atexit(release_pythonfmu_state); /* after pythonfmu3's static constructors: runs before its destructors */
        exit_handler_registered = 1;
    }
    return 1;
}

/* ---- the guard (guard.h) in FMI 3.0's names ---- */
typedef fmi3Status Status;
#define STATUS(name) fmi3##name
#define FMI "fmi3"
#define INSTANCE_TYPE "fmi3Instance"
#define STATE_TYPE "fmi3FMUState"
#define STATE_ARGUMENT "FMUState"
#define GET_STATE "fmi3GetFMUState"
#define DESERIALIZE_STATE "fmi3DeserializeFMUState"
#define SERIALIZED_STATE_SIZE "fmi3SerializedFMUStateSize"
typedef struct {
    fmi3InstanceEnvironment environment;
    fmi3LogMessageCallback log; /* may be NULL: lines go to stderr */
} HostCallbacks;
#define PHASE_NAMES "instantiated", "initializationMode", "stepMode", "stepDiscarded", "stepCanceled", "terminated", \
                    "error", "fatal"
#define TYPE_NAME_R "Float64"
#define TYPE_NAME_I "Int32"
#define TYPE_NAME_L "Int64 (Enumeration)"
#include "guard.h"
#include "states.h"

static void host_log(const GuardedInstance *in, Status status, const char *category, const char *text) {
    if (in->host.log != NULL)
        in->host.log(in->host.environment, status, category, text);
    else
        fprintf(stderr, "greyfmu: %s: %s\n", in->name, text);
}

/* pythonfmu3's logger, given to it with the instance as the environment (guard.h, guard_message). */
static void guard_logger(fmi3InstanceEnvironment environment, fmi3Status status, fmi3String category,
                         fmi3String message) {
    guard_message(environment, status, category, message);
}

/* This FMU's loader ready: a Python running in the process and pythonfmu3's library loaded. */
static int ensure_loaded(char *problem, size_t size) {
    if (pythonfmu_library != NULL) return 1;
    char *root = malloc(PATH_MAX);
    if (root == NULL) {
        append(problem, size, "out of memory loading the FMU's Python");
        return 0;
    }
    PythonApi api;
    int ok = fmu_root(root, PATH_MAX);
    if (!ok) append(problem, size, "cannot locate the FMU's folder from its binary");
    ok = ok && start_process_python(root, &api, problem, size) && load_pythonfmu(root, problem, size);
    if (ok) {
        python_api = api;
        snprintf(resources, sizeof resources, "%s%cresources", root, SEPARATOR);
    }
    free(root);
    return ok;
}

/* After each forwarded fmi3InstantiateCoSimulation: `slave_class`, the class pythonfmu3 took (the
 * name in the stub <module>.py it read, asked of the slave module), which the guard serialises FMU
 * states with; an instantiation that failed before the slave took its folder off sys.path again
 * leaves pythonfmu3's entry: taken off here. */
static const char FINISH_INSTANCE[] =
    "import os, re, sys\n"
    "found = sys.modules.get(module)\n"
    "if found is not None and failed == '0':\n"
    "    with open(os.path.join(folder, module + '.py'), encoding='utf-8') as stub:\n"
    "        named = re.search(r'^class (\\w+)\\(', stub.read(), re.M)\n"
    "    slave_class = getattr(found, named.group(1)) if named else None\n"
    "if failed == '1' and sys.path.count(folder) > int(paths):\n"
    "    sys.path.remove(folder)\n";

static void keep_slave_class(PythonApi *api, void *globals, void *context) {
    GuardedInstance *in = context;
    void *slave_class = api->DictGetItemString(globals, "slave_class");
    if (in->real != NULL && slave_class != NULL) {
        api->IncRef(slave_class);
        in->slave_class = slave_class;
    }
}

static void finish_instance(GuardedInstance *in, const char *folder, char *module, char *paths) {
    PyVariable variables[] = {{"folder", (char *)folder, 0}, {"module", module, 0}, {"paths", paths, 0},
                              {"failed", in->real == NULL ? "1" : "0", 0}};
    if (!run_in_process(&python_api, FINISH_INSTANCE, "<greyfmu loader>", variables, 4, keep_slave_class, in))
        fprintf(stderr, "greyfmu: fmi3InstantiateCoSimulation: finding the slave class raised a Python exception "
                        "(printed above)\n");
}

/* ---- the exported FMI 3.0 functions, behind the guard (guard.h) ---- */

EXPORT const char *fmi3GetVersion(void) { return "3.0"; }

/* An instantiation refused before there is an instance: one line through the host's logger. */
static fmi3Instance refuse_instance(const HostCallbacks *host, const char *format, ...) {
    enum { TEXT = 16384 };
    char *text = malloc(TEXT);
    if (text != NULL) {
        va_list args;
        va_start(args, format);
        vsnprintf(text, TEXT, format, args);
        va_end(args);
    }
    const char *line = text != NULL ? text : "fmi3InstantiateCoSimulation: refused, and out of memory to say why";
    if (host->log != NULL)
        host->log(host->environment, fmi3Error, "logStatusError", line);
    else
        fprintf(stderr, "greyfmu: %s\n", line);
    free(text);
    return NULL;
}

EXPORT fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                                 fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                                 fmi3InstanceEnvironment instanceEnvironment,
                                                 fmi3LogMessageCallback logMessage) {
    (void)instanceName, (void)instantiationToken, (void)resourcePath, (void)visible, (void)loggingOn;
    HostCallbacks host = {instanceEnvironment, logMessage};
    return refuse_instance(&host, "fmi3InstantiateModelExchange: this FMU is Co-Simulation only, it has no Model "
                           "Exchange interface");
}

EXPORT fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                                      fmi3String resourcePath, fmi3Boolean visible,
                                                      fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
                                                      fmi3LogMessageCallback logMessage, void *clockUpdate,
                                                      void *lockPreemption, void *unlockPreemption) {
    (void)instanceName, (void)instantiationToken, (void)resourcePath, (void)visible, (void)loggingOn;
    (void)clockUpdate, (void)lockPreemption, (void)unlockPreemption;
    HostCallbacks host = {instanceEnvironment, logMessage};
    return refuse_instance(&host, "fmi3InstantiateScheduledExecution: this FMU is Co-Simulation only, it has no "
                           "Scheduled Execution interface");
}

/* The guard's checks of fmi3InstantiateCoSimulation's arguments; the instance (model read,
 * resources folder found) or NULL after one line. */
static GuardedInstance *new_instance(fmi3String name, fmi3String token, fmi3String location, fmi3Boolean event_mode,
                                     size_t n_intermediate, const HostCallbacks *host, fmi3Boolean logging_on,
                                     char *folder, size_t size) {
    if (name == NULL || *name == '\0')
        return refuse_instance(host, "fmi3InstantiateCoSimulation: instanceName is %s", name ? "empty" : "NULL");
    if (event_mode)
        return refuse_instance(host, "fmi3InstantiateCoSimulation: eventModeUsed = true, but this FMU has no event "
                               "mode (hasEventMode = false)");
    if (n_intermediate > 0)
        return refuse_instance(host, "fmi3InstantiateCoSimulation: nRequiredIntermediateVariables = %zu, but this FMU "
                               "provides no intermediate update (providesIntermediateUpdate = false)", n_intermediate);
    struct {
        char root[PATH_MAX], own[PATH_MAX + 16], problem[4096];
    } *scratch = calloc(1, sizeof *scratch);
    GuardedInstance *in = calloc(1, sizeof *in);
    if (scratch == NULL || in == NULL) {
        free(scratch);
        free(in);
        return refuse_instance(host, "fmi3InstantiateCoSimulation: out of memory");
    }
    char *root = scratch->root, *own = scratch->own, *problem = scratch->problem;
    int fallback = 0, ok = fmu_root(root, sizeof scratch->root);
    if (!ok) {
        refuse_instance(host, "fmi3InstantiateCoSimulation: cannot locate the FMU's folder from its binary");
    } else if (snprintf(own, sizeof scratch->own, "%s%cresources", root, SEPARATOR),
               !resource_folder(location, root, folder, size, &fallback, problem, sizeof scratch->problem)) {
        refuse_instance(host, "fmi3InstantiateCoSimulation: resourcePath '%s' %s", location, problem);
        ok = 0;
    } else if (strstr(folder, "%20") != NULL) {
        refuse_instance(host, "fmi3InstantiateCoSimulation: resourcePath '%s' holds '%%20', which pythonfmu3 0.3.4 "
                        "reads as a space: move the FMU's files to a folder without it", location);
        ok = 0;
    } else if (!read_model(own, &in->model, problem, sizeof scratch->problem) &&
               !read_model(folder, &in->model, problem, sizeof scratch->problem)) {
        refuse_instance(host, "fmi3InstantiateCoSimulation: %s", problem);
        ok = 0;
    } else if (token == NULL || strcmp(token, in->model.guid) != 0) {
        refuse_instance(host, "fmi3InstantiateCoSimulation: instantiationToken %s%s%s is not this FMU's %s",
                        token ? "'" : "", token ? token : "NULL", token ? "'" : "", in->model.guid);
        ok = 0;
    }
    free(scratch);
    if (ok && (in->name = strdup(name)) == NULL) {
        refuse_instance(host, "fmi3InstantiateCoSimulation: out of memory");
        ok = 0;
    }
    if (!ok) {
        free_model(&in->model);
        free(in);
        return NULL;
    }
    in->host = *host;
    in->phase = PHASE_INSTANTIATED;
    in->logging_on = logging_on != 0;
    in->magic = GUARD_MAGIC;
    if (fallback)
        host_log(in, fmi3Warning, "logStatusWarning",
                 "fmi3InstantiateCoSimulation: resourcePath is NULL or empty: using the FMU's own resources folder");
    return in;
}

EXPORT fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                                fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                                fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                                const fmi3ValueReference requiredIntermediateVariables[],
                                                size_t nRequiredIntermediateVariables,
                                                fmi3InstanceEnvironment instanceEnvironment,
                                                fmi3LogMessageCallback logMessage,
                                                fmi3IntermediateUpdateCallback intermediateUpdate) {
    (void)earlyReturnAllowed, (void)requiredIntermediateVariables, (void)intermediateUpdate;
    HostCallbacks host = {instanceEnvironment, logMessage};
    /* Every buffer on the heap: a host may call from a thread with a small stack. */
    struct {
        char folder[PATH_MAX + 16], problem[16384], module[512], paths[32];
    } *scratch = calloc(1, sizeof *scratch);
    if (scratch == NULL) return refuse_instance(&host, "fmi3InstantiateCoSimulation: out of memory");
    char *folder = scratch->folder, *problem = scratch->problem;
    GuardedInstance *in = new_instance(instanceName, instantiationToken, resourcePath, eventModeUsed,
                                       nRequiredIntermediateVariables, &host, loggingOn, folder, sizeof scratch->folder);
    if (in == NULL) {
        free(scratch);
        return NULL;
    }
    save_signals(&in->signals); /* Python may be started, and its signal module imported, below */
    lock(&load_lock);
    int ready = ensure_loaded(problem, sizeof scratch->problem);
    unlock(&load_lock);
    ready = ready && prepare_instance(folder, scratch->module, sizeof scratch->module, scratch->paths,
                                      sizeof scratch->paths, problem, sizeof scratch->problem);
    if (ready) {
        typedef fmi3Instance (*Instantiate)(fmi3String, fmi3String, fmi3String, fmi3Boolean, fmi3Boolean, fmi3Boolean,
                                            fmi3Boolean, const fmi3ValueReference[], size_t, fmi3InstanceEnvironment,
                                            fmi3LogMessageCallback, fmi3IntermediateUpdateCallback);
        /* loggingOn for pythonfmu3, whose debug lines are otherwise dropped: the guard filters */
        in->real = ((Instantiate)real_fmi3InstantiateCoSimulation)(instanceName, instantiationToken, folder, visible, 1,
                                                                    0, 0, NULL, 0, in, guard_logger, NULL);
        finish_instance(in, folder, scratch->module, scratch->paths);
    }
    restore_signals(&in->signals);
    if (in->real == NULL) {
        if (!ready)
            refuse_instance(&host, "greyfmu: %s", problem);
        else if (!in->explained)
            refuse_instance(&host, "fmi3InstantiateCoSimulation: pythonfmu3 returned no instance without saying why");
        free_guarded(in);
        free(scratch);
        return NULL;
    }
    free(scratch);
    lock(&load_lock);
    live_instances++;
    unlock(&load_lock);
    return in;
}

/* As fmi2FreeInstance (fmi2_loader.c): an instance pythonfmu3 gave up on (fmi3Fatal) frees only
 * the guard's record. */
EXPORT void fmi3FreeInstance(fmi3Instance c) {
    if (c == NULL) return;
    GuardedInstance *in = guarded(c, "fmi3FreeInstance");
    if (in == NULL) return;
    save_signals(&in->signals);
    if (in->phase != PHASE_FATAL && real_fmi3FreeInstance != NULL) ((void (*)(fmi3Instance))real_fmi3FreeInstance)(in->real);
    if (real_fmi3FreeInstance != NULL) release_instance_objects(in);
    restore_signals(&in->signals);
    free_guarded(in);
    if (real_fmi3FreeInstance == NULL) return;
    lock(&load_lock);
    if (--live_instances == 0) release_pythonfmu_state();
    unlock(&load_lock);
}

#define CALL(name, params, ...) (((fmi3Status(*) params)real_##name)(in->real, __VA_ARGS__))
#define CALL_PLAIN(name) (((fmi3Status(*)(fmi3Instance))real_##name)(in->real))
#define GUARDED(name, phases)                                                                                      \
    GuardedInstance *in = guarded(c, #name);                                                                       \
    if (in == NULL) return fmi3Error;                                                                              \
    if (!allowed_in(in, #name, phases)) return fmi3Error;                                                          \
    in->explained = in->recoverable = 0;
#define KEEPING_HOST_SIGNALS(status, call)                                                                         \
    save_signals(&in->signals);                                                                                    \
    fmi3Status status = (call);                                                                                    \
    restore_signals(&in->signals);

EXPORT fmi3Status fmi3SetDebugLogging(fmi3Instance c, fmi3Boolean loggingOn, size_t nCategories,
                                      const fmi3String categories[]) {
    GUARDED(fmi3SetDebugLogging, PHASES_ANY_BUT_FATAL)
    return debug_logging(in, "fmi3SetDebugLogging", loggingOn != 0, nCategories, categories);
}

/* The independent variable `time`, through which the start time reaches the slave (fmus/fmi3/_slave3.py). */
static const GuardVariable *independent(const GuardModel *model) {
    for (size_t i = 0; i < model->count; i++)
        if (strcmp(model->variables[i].causality, "independent") == 0) return &model->variables[i];
    return NULL;
}

EXPORT fmi3Status fmi3EnterInitializationMode(fmi3Instance c, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                              fmi3Float64 startTime, fmi3Boolean stopTimeDefined,
                                              fmi3Float64 stopTime) {
    GUARDED(fmi3EnterInitializationMode, PHASE_INSTANTIATED)
    if (!isfinite(startTime)) REFUSE(in, "fmi3EnterInitializationMode", "startTime = %g is not finite", startTime);
    if (stopTimeDefined && !(isfinite(stopTime) && stopTime >= startTime))
        REFUSE(in, "fmi3EnterInitializationMode", "stopTime = %g is not a finite time >= startTime = %g", stopTime,
               startTime);
    const GuardVariable *time = independent(&in->model);
    if (time == NULL) REFUSE(in, "fmi3EnterInitializationMode", "the FMU declares no independent variable (damaged?)");
    fmi3ValueReference vr = time->vr;
    KEEPING_HOST_SIGNALS(given, CALL(fmi3SetFloat64, (fmi3Instance, const fmi3ValueReference[], size_t,
                                                      const fmi3Float64[], size_t), &vr, 1, &startTime, 1))
    fmi3Status status = given;
    if (given <= fmi3Warning) {
        save_signals(&in->signals);
        status = CALL(fmi3EnterInitializationMode, (fmi3Instance, fmi3Boolean, fmi3Float64, fmi3Float64, fmi3Boolean,
                                                    fmi3Float64), toleranceDefined, tolerance, startTime,
                      stopTimeDefined, stopTime);
        restore_signals(&in->signals);
    }
    if (status <= fmi3Warning) {
        in->time_known = 1;
        in->next_time = startTime;
        in->stop_defined = stopTimeDefined != 0;
        in->stop_time = stopTime;
    }
    return settle(in, "fmi3EnterInitializationMode", status, PHASE_INITIALIZATION);
}

EXPORT fmi3Status fmi3ExitInitializationMode(fmi3Instance c) {
    GUARDED(fmi3ExitInitializationMode, PHASE_INITIALIZATION)
    KEEPING_HOST_SIGNALS(status, CALL_PLAIN(fmi3ExitInitializationMode))
    return settle(in, "fmi3ExitInitializationMode", status, PHASE_STEP_COMPLETE);
}

EXPORT fmi3Status fmi3Terminate(fmi3Instance c) {
    GUARDED(fmi3Terminate, PHASE_STEP_COMPLETE | PHASE_STEP_FAILED)
    KEEPING_HOST_SIGNALS(status, CALL_PLAIN(fmi3Terminate))
    return settle(in, "fmi3Terminate", status, PHASE_TERMINATED);
}

EXPORT fmi3Status fmi3Reset(fmi3Instance c) {
    GUARDED(fmi3Reset, PHASES_ANY_BUT_FATAL)
    KEEPING_HOST_SIGNALS(status, CALL_PLAIN(fmi3Reset))
    if (status <= fmi3Warning) in->time_known = in->stop_defined = 0;
    return settle(in, "fmi3Reset", status, PHASE_INSTANTIATED);
}

/* nValues = nvr: every variable of this FMU is a scalar. */
static int values_ok(GuardedInstance *in, const char *function, size_t nvr, size_t n_values) {
    if (n_values == nvr) return 1;
    guard_say(in, fmi3Error, function, "nValues = %zu, but the %zu variables named hold %zu values (every variable "
              "of this FMU is a scalar)", n_values, nvr, nvr);
    enter_error(in);
    return 0;
}

/* fmi3Get<Type> and fmi3Set<Type> of the types the FMU has: the state, the arrays, nValues, every
 * value reference (and for a set, whether each variable may be set now); nothing is forwarded for
 * nvr = 0. */
#define GET_SET(name, T, letter, phases, setting)                                                                  \
    EXPORT fmi3Status name(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, T values[], size_t nValues) { \
        GUARDED(name, phases)                                                                                      \
        if (!values_ok(in, #name, nvr, nValues) || !references_ok(in, #name, vr, nvr, values, letter, setting))   \
            return fmi3Error;                                                                                      \
        if (nvr == 0) return fmi3OK;                                                                               \
        return settle(in, #name,                                                                                   \
                      CALL(name, (fmi3Instance, const fmi3ValueReference[], size_t, T[], size_t), vr, nvr, values, \
                           nValues),                                                                               \
                      0);                                                                                          \
    }
GET_SET(fmi3GetFloat64, fmi3Float64, 'R', PHASES_GET, 0)
GET_SET(fmi3GetInt32, fmi3Int32, 'I', PHASES_GET, 0)
GET_SET(fmi3GetInt64, fmi3Int64, 'L', PHASES_GET, 0)
GET_SET(fmi3GetBoolean, fmi3Boolean, 'B', PHASES_GET, 0)
GET_SET(fmi3GetString, fmi3String, 'S', PHASES_GET, 0)
GET_SET(fmi3SetFloat64, const fmi3Float64, 'R', PHASES_SET, 1)
GET_SET(fmi3SetInt32, const fmi3Int32, 'I', PHASES_SET, 1)
GET_SET(fmi3SetInt64, const fmi3Int64, 'L', PHASES_SET, 1)
GET_SET(fmi3SetBoolean, const fmi3Boolean, 'B', PHASES_SET, 1)
GET_SET(fmi3SetString, const fmi3String, 'S', PHASES_SET, 1)

/* The types the FMU has no variable of: answered by the guard (any value reference is refused). */
static fmi3Status no_such_type(GuardedInstance *in, const char *function, const char *type, const fmi3ValueReference vr[],
                               size_t nvr, const void *values, size_t n_values) {
    if (!values_ok(in, function, nvr, n_values)) return fmi3Error;
    if (nvr == 0) return fmi3OK;
    if (vr == NULL) REFUSE(in, function, "the value reference array vr is NULL with nvr = %zu", nvr);
    if (values == NULL) REFUSE(in, function, "the value array is NULL with nvr = %zu", nvr);
    const GuardVariable *v = any_variable(&in->model, vr[0]);
    if (v == NULL) REFUSE(in, function, "vr[0] = %u is not a value reference of this FMU", vr[0]);
    REFUSE(in, function, "vr[0] = %u is %s, a %s variable: this FMU has no %s variables", vr[0], v->name,
           type_name(v->type), type);
}

#define NO_SUCH_TYPE(name, T, type, phases)                                                                        \
    EXPORT fmi3Status name(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, T values[], size_t nValues) { \
        GUARDED(name, phases)                                                                                      \
        return no_such_type(in, #name, type, vr, nvr, values, nValues);                                            \
    }
NO_SUCH_TYPE(fmi3GetFloat32, fmi3Float32, "Float32", PHASES_GET)
NO_SUCH_TYPE(fmi3GetInt8, fmi3Int8, "Int8", PHASES_GET)
NO_SUCH_TYPE(fmi3GetUInt8, fmi3UInt8, "UInt8", PHASES_GET)
NO_SUCH_TYPE(fmi3GetInt16, fmi3Int16, "Int16", PHASES_GET)
NO_SUCH_TYPE(fmi3GetUInt16, fmi3UInt16, "UInt16", PHASES_GET)
NO_SUCH_TYPE(fmi3GetUInt32, fmi3UInt32, "UInt32", PHASES_GET)
NO_SUCH_TYPE(fmi3GetUInt64, fmi3UInt64, "UInt64", PHASES_GET)
NO_SUCH_TYPE(fmi3SetFloat32, const fmi3Float32, "Float32", PHASES_SET)
NO_SUCH_TYPE(fmi3SetInt8, const fmi3Int8, "Int8", PHASES_SET)
NO_SUCH_TYPE(fmi3SetUInt8, const fmi3UInt8, "UInt8", PHASES_SET)
NO_SUCH_TYPE(fmi3SetInt16, const fmi3Int16, "Int16", PHASES_SET)
NO_SUCH_TYPE(fmi3SetUInt16, const fmi3UInt16, "UInt16", PHASES_SET)
NO_SUCH_TYPE(fmi3SetUInt32, const fmi3UInt32, "UInt32", PHASES_SET)
NO_SUCH_TYPE(fmi3SetUInt64, const fmi3UInt64, "UInt64", PHASES_SET)

EXPORT fmi3Status fmi3GetBinary(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, size_t valueSizes[],
                                fmi3Binary values[], size_t nValues) {
    GUARDED(fmi3GetBinary, PHASES_GET)
    if (nvr > 0 && valueSizes == NULL) REFUSE(in, "fmi3GetBinary", "valueSizes is NULL with nValueReferences = %zu", nvr);
    return no_such_type(in, "fmi3GetBinary", "Binary", vr, nvr, values, nValues);
}

EXPORT fmi3Status fmi3SetBinary(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, const size_t valueSizes[],
                                const fmi3Binary values[], size_t nValues) {
    GUARDED(fmi3SetBinary, PHASES_SET)
    if (nvr > 0 && valueSizes == NULL) REFUSE(in, "fmi3SetBinary", "valueSizes is NULL with nValueReferences = %zu", nvr);
    return no_such_type(in, "fmi3SetBinary", "Binary", vr, nvr, values, nValues);
}

/* What this FMU does not have: one line saying so, fmi3Error (the instance's state is kept: nothing ran). */
static fmi3Status not_provided(fmi3Instance c, const char *function, const char *why) {
    GuardedInstance *in = guarded(c, function);
    if (in == NULL) return fmi3Error;
    if (in->phase == PHASE_FATAL) {
        guard_say(in, fmi3Error, function, "not allowed: the instance returned fmi3Fatal, only fmi3FreeInstance is");
        return fmi3Error;
    }
    guard_say(in, fmi3Error, function, "%s", why);
    enter_error(in);
    return fmi3Error;
}

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-parameter" /* the arguments of what is not provided are not looked at */
#define NOT_PROVIDED(name, why, ...)                                                                               \
    EXPORT fmi3Status name(fmi3Instance c, ##__VA_ARGS__) { return not_provided(c, #name, why); }
#define CO_SIMULATION_ONLY "this FMU is Co-Simulation only, without event mode (hasEventMode = false)"
#define NO_CLOCKS "this FMU has no clocks"
NOT_PROVIDED(fmi3EnterEventMode, CO_SIMULATION_ONLY)
NOT_PROVIDED(fmi3EnterStepMode, "the instance enters step mode by fmi3ExitInitializationMode (hasEventMode = false)")
NOT_PROVIDED(fmi3EnterConfigurationMode, "this FMU has no structural parameters")
NOT_PROVIDED(fmi3ExitConfigurationMode, "this FMU has no structural parameters")
NOT_PROVIDED(fmi3EvaluateDiscreteStates, CO_SIMULATION_ONLY)
NOT_PROVIDED(fmi3EnterContinuousTimeMode, CO_SIMULATION_ONLY)
NOT_PROVIDED(fmi3GetClock, NO_CLOCKS, const fmi3ValueReference vr[], size_t n, fmi3Clock values[])
NOT_PROVIDED(fmi3SetClock, NO_CLOCKS, const fmi3ValueReference vr[], size_t n, const fmi3Clock values[])
NOT_PROVIDED(fmi3GetIntervalDecimal, NO_CLOCKS, const fmi3ValueReference vr[], size_t n, fmi3Float64 intervals[],
             fmi3IntervalQualifier qualifiers[])
NOT_PROVIDED(fmi3GetIntervalFraction, NO_CLOCKS, const fmi3ValueReference vr[], size_t n, fmi3UInt64 counters[],
             fmi3UInt64 resolutions[], fmi3IntervalQualifier qualifiers[])
NOT_PROVIDED(fmi3GetShiftDecimal, NO_CLOCKS, const fmi3ValueReference vr[], size_t n, fmi3Float64 shifts[])
NOT_PROVIDED(fmi3GetShiftFraction, NO_CLOCKS, const fmi3ValueReference vr[], size_t n, fmi3UInt64 counters[],
             fmi3UInt64 resolutions[])
NOT_PROVIDED(fmi3SetIntervalDecimal, NO_CLOCKS, const fmi3ValueReference vr[], size_t n, const fmi3Float64 intervals[])
NOT_PROVIDED(fmi3SetIntervalFraction, NO_CLOCKS, const fmi3ValueReference vr[], size_t n,
             const fmi3UInt64 counters[], const fmi3UInt64 resolutions[])
NOT_PROVIDED(fmi3SetShiftDecimal, NO_CLOCKS, const fmi3ValueReference vr[], size_t n, const fmi3Float64 shifts[])
NOT_PROVIDED(fmi3SetShiftFraction, NO_CLOCKS, const fmi3ValueReference vr[], size_t n, const fmi3UInt64 counters[],
             const fmi3UInt64 resolutions[])
NOT_PROVIDED(fmi3ActivateModelPartition, "this FMU is Co-Simulation only, it has no Scheduled Execution interface",
             fmi3ValueReference clock, fmi3Float64 activationTime)
NOT_PROVIDED(fmi3GetNumberOfVariableDependencies, "this FMU does not provide variable dependencies at run time "
             "(its modelDescription.xml lists them)", fmi3ValueReference vr, size_t *n)
NOT_PROVIDED(fmi3GetVariableDependencies, "this FMU does not provide variable dependencies at run time (its "
             "modelDescription.xml lists them)", fmi3ValueReference dependent, size_t elements[],
             fmi3ValueReference independents[], size_t independentElements[], fmi3DependencyKind kinds[], size_t n)
NOT_PROVIDED(fmi3GetDirectionalDerivative, "this FMU provides no directional derivatives "
             "(providesDirectionalDerivatives = false)", const fmi3ValueReference unknowns[], size_t nUnknowns,
             const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[], size_t nSeed,
             fmi3Float64 sensitivity[], size_t nSensitivity)
NOT_PROVIDED(fmi3GetAdjointDerivative, "this FMU provides no adjoint derivatives (providesAdjointDerivatives = false)",
             const fmi3ValueReference unknowns[], size_t nUnknowns, const fmi3ValueReference knowns[], size_t nKnowns,
             const fmi3Float64 seed[], size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity)
NOT_PROVIDED(fmi3GetOutputDerivatives, "this FMU provides no output derivatives (maxOutputDerivativeOrder = 0)",
             const fmi3ValueReference vr[], size_t n, const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues)
NOT_PROVIDED(fmi3UpdateDiscreteStates, CO_SIMULATION_ONLY, fmi3Boolean *needUpdate, fmi3Boolean *terminate,
             fmi3Boolean *nominalsChanged, fmi3Boolean *valuesChanged, fmi3Boolean *nextDefined, fmi3Float64 *next)
NOT_PROVIDED(fmi3CompletedIntegratorStep, CO_SIMULATION_ONLY, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
             fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation)
NOT_PROVIDED(fmi3SetTime, CO_SIMULATION_ONLY, fmi3Float64 time)
NOT_PROVIDED(fmi3SetContinuousStates, CO_SIMULATION_ONLY, const fmi3Float64 states[], size_t n)
NOT_PROVIDED(fmi3GetContinuousStateDerivatives, CO_SIMULATION_ONLY, fmi3Float64 derivatives[], size_t n)
NOT_PROVIDED(fmi3GetEventIndicators, CO_SIMULATION_ONLY, fmi3Float64 indicators[], size_t n)
NOT_PROVIDED(fmi3GetContinuousStates, CO_SIMULATION_ONLY, fmi3Float64 states[], size_t n)
NOT_PROVIDED(fmi3GetNominalsOfContinuousStates, CO_SIMULATION_ONLY, fmi3Float64 nominals[], size_t n)
NOT_PROVIDED(fmi3GetNumberOfEventIndicators, CO_SIMULATION_ONLY, size_t *n)
NOT_PROVIDED(fmi3GetNumberOfContinuousStates, CO_SIMULATION_ONLY, size_t *n)
#pragma GCC diagnostic pop

/* FMU states: states.h, as in FMI 2.0. */
EXPORT fmi3Status fmi3GetFMUState(fmi3Instance c, fmi3FMUState *state) {
    GUARDED(fmi3GetFMUState, PHASES_ANY_BUT_FATAL)
    return get_state(in, "fmi3GetFMUState", state, (Status(*)(void *, void **))real_fmi3GetFMUState);
}

EXPORT fmi3Status fmi3SetFMUState(fmi3Instance c, fmi3FMUState state) {
    GUARDED(fmi3SetFMUState, PHASES_ANY_BUT_FATAL)
    return set_state(in, "fmi3SetFMUState", state, (Status(*)(void *, void *))real_fmi3SetFMUState);
}

EXPORT fmi3Status fmi3FreeFMUState(fmi3Instance c, fmi3FMUState *state) {
    GUARDED(fmi3FreeFMUState, PHASES_ANY_BUT_FATAL)
    return free_state(in, "fmi3FreeFMUState", state);
}

EXPORT fmi3Status fmi3SerializedFMUStateSize(fmi3Instance c, fmi3FMUState state, size_t *size) {
    GUARDED(fmi3SerializedFMUStateSize, PHASES_ANY_BUT_FATAL)
    return serialized_state_size(in, "fmi3SerializedFMUStateSize", state, size);
}

EXPORT fmi3Status fmi3SerializeFMUState(fmi3Instance c, fmi3FMUState state, fmi3Byte bytes[], size_t size) {
    GUARDED(fmi3SerializeFMUState, PHASES_ANY_BUT_FATAL)
    return serialize_state(in, "fmi3SerializeFMUState", state, (char *)bytes, size);
}

EXPORT fmi3Status fmi3DeserializeFMUState(fmi3Instance c, const fmi3Byte bytes[], size_t size, fmi3FMUState *state) {
    GUARDED(fmi3DeserializeFMUState, PHASES_ANY_BUT_FATAL)
    return deserialize_state(in, "fmi3DeserializeFMUState", (const char *)bytes, size, state);
}

EXPORT fmi3Status fmi3DoStep(fmi3Instance c, fmi3Float64 currentCommunicationPoint, fmi3Float64 communicationStepSize,
                             fmi3Boolean noSetFMUStatePriorToCurrentPoint, fmi3Boolean *eventHandlingNeeded,
                             fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn,
                             fmi3Float64 *lastSuccessfulTime) {
    GUARDED(fmi3DoStep, PHASE_STEP_COMPLETE)
    double t = currentCommunicationPoint, h = communicationStepSize;
    if (eventHandlingNeeded == NULL || terminateSimulation == NULL || earlyReturn == NULL || lastSuccessfulTime == NULL)
        REFUSE(in, "fmi3DoStep", "%s is NULL (FMI 3.0 requires each output argument)",
               eventHandlingNeeded == NULL ? "eventHandlingNeeded" : terminateSimulation == NULL ? "terminateSimulation"
               : earlyReturn == NULL ? "earlyReturn" : "lastSuccessfulTime");
    if (!isfinite(t)) REFUSE(in, "fmi3DoStep", "currentCommunicationPoint = %g is not finite", t);
    if (!(isfinite(h) && h > 0)) REFUSE(in, "fmi3DoStep", "communicationStepSize = %g: a step must be finite and > 0", h);
    if (in->model.max_step > 0 && h > in->model.max_step)
        REFUSE(in, "fmi3DoStep",
               "communicationStepSize = %g s is longer than this FMU's longest step, %g s (10^4 DefaultExperiment "
               "steps: the FMU computes every internal sample of a step)",
               h, in->model.max_step);
    if (!isfinite(t + h)) REFUSE(in, "fmi3DoStep", "currentCommunicationPoint + communicationStepSize is not finite");
    if (in->time_known && !same_time(t, in->next_time))
        REFUSE(in, "fmi3DoStep",
               "currentCommunicationPoint = %.17g s, but the instance is at %.17g s (a step starts where the last one "
               "ended; fmi3SetFMUState moves the time)",
               t, in->next_time);
    if (in->stop_defined && t + h > in->stop_time && !same_time(t + h, in->stop_time))
        REFUSE(in, "fmi3DoStep", "the step [%.17g, %.17g] s ends after stopTime = %.17g s (fmi3EnterInitializationMode)",
               t, t + h, in->stop_time);
    *eventHandlingNeeded = *terminateSimulation = *earlyReturn = 0;
    *lastSuccessfulTime = t;
    fmi3Status status = CALL(fmi3DoStep, (fmi3Instance, fmi3Float64, fmi3Float64, fmi3Boolean, fmi3Boolean *,
                                          fmi3Boolean *, fmi3Boolean *, fmi3Float64 *),
                             t, h, noSetFMUStatePriorToCurrentPoint, eventHandlingNeeded, terminateSimulation,
                             earlyReturn, lastSuccessfulTime);
    if (status <= fmi3Warning) {
        in->time_known = 1;
        in->next_time = t + h;
    }
    return settle(in, "fmi3DoStep", status, status == fmi3Discard ? PHASE_STEP_FAILED : PHASE_STEP_COMPLETE);
}

/* Unload: as fmi2_loader.c's (pythonfmu3's state released, then its library). */
__attribute__((destructor)) static void unload_loader(void) {
    forget_process();
    if (pythonfmu_library == NULL || live_instances > 0) return;
    free(states);
    states = NULL;
    state_count = state_capacity = 0;
#ifndef _WIN32
    release_pythonfmu_state();
    dlclose(pythonfmu_library);
    pythonfmu_library = NULL;
#endif
}
