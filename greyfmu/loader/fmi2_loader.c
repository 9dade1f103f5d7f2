/* greyfmu drop-in loader: the linux64 binary of every greyfmu FMI 2.0 Co-Simulation FMU.
 *
 * pythonfmu 0.7.0's library (shipped next to this one as pythonfmu-export.so, .dll on Windows)
 * does not link libpython on Linux, so it only loads in a process that already has Python; on
 * Windows it needs python3.dll on PATH.  This loader is the binary the host opens
 * (binaries/linux64/<modelIdentifier>.so, binaries/win64/<modelIdentifier>.dll; the platform
 * layer is platform.h).  On the first fmi2Instantiate:
 *
 *   1. If the host process already runs an initialised Python (fmpy, cosim), that one is used,
 *      however libpython is linked (platform.h, loaded_python); a libpython loaded but not
 *      initialised is initialised below only if it is the chosen candidate's: never a second one.
 *   2. Otherwise a Python is chosen in this order (README, "The FMUs"):
 *        a. the interpreter named by the environment variable GREYFMU_PYTHON (no fallback if set),
 *        b. the interpreter that built the FMU (resources/greyfmu_build_python.txt),
 *        c. python3 on PATH.
 *      The candidate runs resources/greyfmu_target.py in a child process (posix_spawn, 60 s
 *      limit) which prints its version, shared libpython, home and sys.path, and checks the
 *      FMU's requirements (resources/greyfmu_requirements.txt).  The first usable candidate's
 *      libpython is loaded with RTLD_GLOBAL (Windows: pythonXY.dll, then python3.dll next to it),
 *      initialised without signal handlers (Py_InitializeEx(0); on Linux with the candidate's home
 *      given by Py_SetPythonHome, never by setenv, which races the getenv of a multithreaded host;
 *      Windows finds the home from the DLL), given the candidate's sys.path (venv site-packages
 *      included) and sys.executable; the GIL is then released.  Paths pass between C and Python
 *      as the file system's bytes (PyUnicode_DecodeFSDefault, os.fsencode), never as UTF-8: a
 *      folder name that is not UTF-8 works or is refused, it does not crash the host.
 *      Python starts once per process, however many FMUs of ours the host loads, under a lock
 *      and a ready flag every greyfmu loader of the process shares (process.c, platform.h
 *      find_process).
 *   3. pythonfmu-export.so is loaded and every fmi2 function forwards to it.  Before each
 *      instantiation the same greyfmu_target.py runs inside the process (Python version >= 3.10
 *      and the requirements) once for the FMU's code, which lives under a package private to
 *      it (greyfmu.privatise; PREPARE_INSTANCE, FINISH_INSTANCE).
 *
 * The host's signal dispositions are put back after every call into Python but a step's
 * (platform.h save_signals, KEEPING_HOST_SIGNALS): Python's signal module installs its SIGINT
 * handler when imported.
 *
 * Every call passes the guard first (guard.h): the fmi2Component the host gets is the guard's
 * record of the instance, and a call the FMI 2.0 state machine, the arguments or the FMU's
 * variables do not allow returns fmi2Error with one log line instead of reaching pythonfmu.
 *
 * Where no usable Python is found, fmi2Instantiate logs one message naming what is missing and
 * how to fix it, and returns NULL.  Python is never finalised (numpy and scipy cannot be
 * re-initialised in one process).
 *
 * Exit and unload: pythonfmu 0.7.0 releases its static std::shared_ptr<PyState> twice when its
 * library is unloaded (the static destructor, then __attribute__((destructor)) onLibraryUnload
 * assigns nullptr to the destroyed pointer), a double free that aborts hosts at exit.  Its
 * exported finalizePythonInterpreter() empties the pointer, after which both releases are
 * no-ops; the loader calls it when the last instance is freed and, for hosts that never free
 * their instances, from an atexit handler registered after the library was loaded (so it runs
 * before that library's static destructors).
 */
#define _GNU_SOURCE
#include "platform.h"
#include "python.h"

/* ---- FMI 2.0 types (fmi2TypesPlatform.h, fmi2FunctionTypes.h) ---- */
typedef void *fmi2Component;
typedef void *fmi2ComponentEnvironment;
typedef void *fmi2FMUstate;
typedef unsigned int fmi2ValueReference;
typedef double fmi2Real;
typedef int fmi2Integer;
typedef int fmi2Boolean;
typedef char fmi2Char;
typedef const fmi2Char *fmi2String;
typedef char fmi2Byte;
typedef enum { fmi2OK, fmi2Warning, fmi2Discard, fmi2Error, fmi2Fatal, fmi2Pending } fmi2Status;
typedef enum { fmi2ModelExchange, fmi2CoSimulation } fmi2Type;
typedef enum { fmi2DoStepStatus, fmi2PendingStatus, fmi2LastSuccessfulTime, fmi2Terminated } fmi2StatusKind;
typedef void (*fmi2CallbackLogger)(fmi2ComponentEnvironment, fmi2String, fmi2Status, fmi2String, fmi2String, ...);
typedef struct {
    fmi2CallbackLogger logger;
    void *(*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void *);
    void (*stepFinished)(fmi2ComponentEnvironment, fmi2Status);
    fmi2ComponentEnvironment componentEnvironment;
} fmi2CallbackFunctions;


static void *pythonfmu_library;
static int live_instances;
static int exit_handler_registered;

/* ---- forwarding: one pointer per fmi2 function of pythonfmu-export.so ---- */
#define FMI2_FUNCTIONS(X)                                                                                          \
    X(fmi2Instantiate)                                                                                             \
    X(fmi2FreeInstance)                                                                                            \
    X(fmi2SetDebugLogging)                                                                                         \
    X(fmi2SetupExperiment)                                                                                         \
    X(fmi2EnterInitializationMode)                                                                                 \
    X(fmi2ExitInitializationMode)                                                                                  \
    X(fmi2Terminate)                                                                                               \
    X(fmi2Reset)                                                                                                   \
    X(fmi2GetReal)                                                                                                 \
    X(fmi2GetInteger)                                                                                              \
    X(fmi2GetBoolean)                                                                                              \
    X(fmi2GetString)                                                                                               \
    X(fmi2SetReal)                                                                                                 \
    X(fmi2SetInteger)                                                                                              \
    X(fmi2SetBoolean)                                                                                              \
    X(fmi2SetString)                                                                                               \
    X(fmi2GetFMUstate)                                                                                             \
    X(fmi2SetFMUstate)                                                                                             \
    X(fmi2FreeFMUstate)                                                                                            \
    X(fmi2SerializedFMUstateSize)                                                                                  \
    X(fmi2SerializeFMUstate)                                                                                       \
    X(fmi2DeSerializeFMUstate)                                                                                     \
    X(fmi2GetDirectionalDerivative)                                                                                \
    X(fmi2SetRealInputDerivatives)                                                                                 \
    X(fmi2GetRealOutputDerivatives)                                                                                \
    X(fmi2DoStep)                                                                                                  \
    X(fmi2CancelStep)                                                                                              \
    X(fmi2GetStatus)                                                                                               \
    X(fmi2GetRealStatus)                                                                                           \
    X(fmi2GetIntegerStatus)                                                                                        \
    X(fmi2GetBooleanStatus)                                                                                        \
    X(fmi2GetStringStatus)

#define DECLARE_POINTER(name) static void *real_##name;
FMI2_FUNCTIONS(DECLARE_POINTER)
static void (*real_finalizePythonInterpreter)(void);

static void release_pythonfmu_state(void) {
    if (real_finalizePythonInterpreter != NULL) real_finalizePythonInterpreter();
}

static int load_pythonfmu(const char *root, char *problem, size_t size) {
    char library[PATH_MAX + 64];
    snprintf(library, sizeof library, "%s%cbinaries%c" PLATFORM_FOLDER "%cpythonfmu-export" LIBRARY_SUFFIX, root,
             SEPARATOR, SEPARATOR, SEPARATOR);
    void *handle = library_open(library, 0, problem, size);
    if (handle == NULL) return 0;
#define LOOK_UP(name)                                                                                              \
    if ((*(void **)&real_##name = library_symbol(handle, #name)) == NULL) {                                       \
        append(problem, size, "%s has no %s", library, #name);                                                     \
        return 0;                                                                                                  \
    }
    FMI2_FUNCTIONS(LOOK_UP)
    LOOK_UP(finalizePythonInterpreter)
#undef LOOK_UP
    pythonfmu_library = handle;
    if (!exit_handler_registered) {
        atexit(release_pythonfmu_state); /* after pythonfmu's static constructors: runs before its destructors */
        exit_handler_registered = 1;
    }
    return 1;
}

/* ---- the guard (guard.h) in FMI 2.0's names ---- */
typedef fmi2Status Status;
#define STATUS(name) fmi2##name
#define FMI "fmi2"
#define INSTANCE_TYPE "fmi2Component"
#define STATE_TYPE "fmi2FMUstate"
#define STATE_ARGUMENT "FMUstate"
#define GET_STATE "fmi2GetFMUstate"
#define DESERIALIZE_STATE "fmi2DeSerializeFMUstate"
#define SERIALIZED_STATE_SIZE "fmi2SerializedFMUstateSize"
typedef fmi2CallbackFunctions HostCallbacks;
#define PHASE_NAMES "instantiated", "initializationMode", "stepComplete", "stepFailed", "stepCanceled", "terminated", \
                    "error", "fatal"
#define TYPE_NAME_R "Real"
#define TYPE_NAME_I "Integer"
#define TYPE_NAME_L "Integer"
#include "guard.h"
#include "states.h"

static void host_log(const GuardedInstance *in, Status status, const char *category, const char *text) {
    in->host.logger(in->host.componentEnvironment, in->name, status, category, "%s", text);
}

/* pythonfmu's logger: it passes each message as the format, with no arguments (guard.h, guard_message). */
static void guard_logger(fmi2ComponentEnvironment environment, fmi2String name, fmi2Status status,
                         fmi2String category, fmi2String message, ...) {
    (void)name; /* the instance's, which the guard holds */
    guard_message(environment, status, category, message);
}

/* This FMU's loader ready: a Python running in the process (started once per process, under the
 * lock every greyfmu loader shares: platform.h find_process) and pythonfmu's library loaded. */
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

/* After each forwarded fmi2Instantiate, whether it gave an instance or not (`failed`):
 *  - pythonfmu 0.7.0's findClass releases the slave module's __dict__, a borrowed reference
 *    (PyModule_GetDict), once per instantiation that got as far as importing the module: after
 *    as many instantiations as the dict has holders it was freed while its module still used it
 *    and the next garbage collection crashed the host (segfault "Garbage-collecting" in
 *    DigitalPI).  One reference is given back per instantiation (`namespace`, Py_IncRef, owned by
 *    no one, as the released one was; `give_back_namespace`).
 *  - `slave_class`: the slave's class, which the guard serialises FMU states with.
 *  - An instantiation that failed before the slave took its folder off sys.path again
 *    (fmus/_inprocess.py) leaves pythonfmu's entry: taken off here. */
static const char FINISH_INSTANCE[] =
    "import sys\n"
    "found = sys.modules.get(module)\n"
    "if found is not None:\n"
    "    namespace = found.__dict__\n"
    "    slave_class = getattr(found, module.rpartition('.')[2], None)\n"
    "if failed == '1' and sys.path.count(folder) > int(paths):\n"
    "    sys.path.remove(folder)\n";

/* What FINISH_INSTANCE left: the namespace's reference given back, the slave class kept (a strong
 * reference) in the instance, unless it failed. */
static void give_back_namespace(PythonApi *api, void *globals, void *context) {
    GuardedInstance *in = context;
    void *namespace = api->DictGetItemString(globals, "namespace");
    if (namespace != NULL) api->IncRef(namespace);
    void *slave_class = api->DictGetItemString(globals, "slave_class");
    if (in->real != NULL && slave_class != NULL) {
        api->IncRef(slave_class);
        in->slave_class = slave_class;
    }
}

/* ---- the exported FMI 2.0 functions, behind the guard (guard.h) ---- */

EXPORT const char *fmi2GetTypesPlatform(void) { return "default"; }

EXPORT const char *fmi2GetVersion(void) { return "2.0"; }

/* An instantiation refused before there is an instance: one line through the host's logger. */
static fmi2Component refuse_instance(const fmi2CallbackFunctions *functions, fmi2String name, const char *format, ...) {
    enum { TEXT = 16384 };
    char *text = malloc(TEXT);
    if (text != NULL) {
        va_list args;
        va_start(args, format);
        vsnprintf(text, TEXT, format, args);
        va_end(args);
    }
    functions->logger(functions->componentEnvironment, name, fmi2Error, "logStatusError", "%s",
                      text != NULL ? text : "fmi2Instantiate: refused, and out of memory to say why");
    free(text);
    return NULL;
}

/* The guard's checks of fmi2Instantiate's arguments; the instance (model read, resources folder
 * found) or NULL after one line. */
static GuardedInstance *new_instance(fmi2String name, fmi2Type type, fmi2String guid, fmi2String location,
                                     const fmi2CallbackFunctions *functions, fmi2Boolean logging_on, char *folder,
                                     size_t size) {
    const char *shown = name != NULL ? name : "";
    if (name == NULL || *name == '\0')
        return refuse_instance(functions, shown, "fmi2Instantiate: instanceName is %s", name ? "empty" : "NULL");
    if (type != fmi2CoSimulation)
        return refuse_instance(functions, name, "fmi2Instantiate: fmuType = %d: this FMU is Co-Simulation only "
                               "(fmi2CoSimulation = 1), it has no Model Exchange interface", (int)type);
    struct {
        char root[PATH_MAX], own[PATH_MAX + 16], problem[4096];
    } *scratch = calloc(1, sizeof *scratch);
    GuardedInstance *in = calloc(1, sizeof *in);
    if (scratch == NULL || in == NULL) {
        free(scratch);
        free(in);
        return refuse_instance(functions, name, "fmi2Instantiate: out of memory");
    }
    char *root = scratch->root, *own = scratch->own, *problem = scratch->problem;
    if (!fmu_root(root, sizeof scratch->root)) {
        free(scratch);
        free(in);
        return refuse_instance(functions, name, "fmi2Instantiate: cannot locate the FMU's folder from its binary");
    }
    snprintf(own, sizeof scratch->own, "%s%cresources", root, SEPARATOR);
    int fallback = 0, ok = resource_folder(location, root, folder, size, &fallback, problem, sizeof scratch->problem);
    if (!ok) {
        refuse_instance(functions, name, "fmi2Instantiate: fmuResourceLocation '%s' %s", location, problem);
    } else if (!read_model(own, &in->model, problem, sizeof scratch->problem) &&
               !read_model(folder, &in->model, problem, sizeof scratch->problem)) { /* fmpy may extract only resources/ */
        refuse_instance(functions, name, "fmi2Instantiate: %s", problem);
        ok = 0;
    } else if (guid == NULL || strcmp(guid, in->model.guid) != 0) {
        refuse_instance(functions, name, "fmi2Instantiate: fmuGUID %s%s%s is not this FMU's GUID %s",
                        guid ? "'" : "", guid ? guid : "NULL", guid ? "'" : "", in->model.guid);
        ok = 0;
    }
    free(scratch);
    if (ok && (in->name = strdup(name)) == NULL) {
        refuse_instance(functions, name, "fmi2Instantiate: out of memory");
        ok = 0;
    }
    if (!ok) {
        free_model(&in->model);
        free(in);
        return NULL;
    }
    if (fallback)
        functions->logger(functions->componentEnvironment, name, fmi2Warning, "logStatusWarning", "%s",
                          "fmi2Instantiate: fmuResourceLocation is NULL or empty: using the FMU's own resources folder");
    in->host = *functions;
    in->forwarded = *functions;
    in->forwarded.logger = guard_logger;
    in->forwarded.componentEnvironment = in;
    in->phase = PHASE_INSTANTIATED;
    in->logging_on = logging_on != 0;
    in->magic = GUARD_MAGIC;
    return in;
}

static void finish_instance(GuardedInstance *in, const char *folder, char *module, char *paths) {
    PyVariable variables[] = {{"folder", (char *)folder, 0}, {"module", module, 0}, {"paths", paths, 0},
                              {"failed", in->real == NULL ? "1" : "0", 0}};
    if (!run_in_process(&python_api, FINISH_INSTANCE, "<greyfmu loader>", variables, 4, give_back_namespace, in))
        fprintf(stderr, "greyfmu: fmi2Instantiate: giving back pythonfmu's reference raised a Python exception "
                        "(printed above)\n");
}

EXPORT fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                                     fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                                     fmi2Boolean visible, fmi2Boolean loggingOn) {
    if (functions == NULL || functions->logger == NULL) {
        fprintf(stderr, "greyfmu: fmi2Instantiate: %s is NULL: FMI 2.0 requires the callbacks and their logger\n",
                functions == NULL ? "functions (the callbacks)" : "functions->logger");
        return NULL;
    }
    /* Every buffer on the heap: a host may call from a thread with a small stack (pythonfmu and
     * Python then have it nearly all; tests/slaves/test_loader_stack.py). */
    struct {
        char folder[PATH_MAX + 16], problem[16384], module[512], paths[32];
    } *scratch = calloc(1, sizeof *scratch);
    if (scratch == NULL)
        return refuse_instance(functions, instanceName ? instanceName : "", "fmi2Instantiate: out of memory");
    char *folder = scratch->folder, *problem = scratch->problem;
    GuardedInstance *in = new_instance(instanceName, fmuType, fmuGUID, fmuResourceLocation, functions, loggingOn,
                                       folder, sizeof scratch->folder);
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
        typedef fmi2Component (*Instantiate)(fmi2String, fmi2Type, fmi2String, fmi2String,
                                             const fmi2CallbackFunctions *, fmi2Boolean, fmi2Boolean);
        /* loggingOn for pythonfmu, whose logger otherwise drops every message: the guard filters */
        in->real = ((Instantiate)real_fmi2Instantiate)(instanceName, fmuType, fmuGUID, folder, &in->forwarded,
                                                       visible, 1);
        finish_instance(in, folder, scratch->module, scratch->paths);
    }
    restore_signals(&in->signals);
    if (in->real == NULL) {
        if (!ready)
            refuse_instance(functions, instanceName, "greyfmu: %s", problem);
        else if (!in->explained)
            refuse_instance(functions, instanceName, "fmi2Instantiate: pythonfmu returned no instance without saying why");
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

/* Instances pythonfmu has given up on (fmi2Fatal: an exception the slave did not say, see guard.h):
 * pythonfmu 0.7.0 answers a Python exception after releasing the instance's Python objects
 * (PySlaveInstance.cpp: handle_py_exception calls cleanPyObject), and releases them again when
 * the instance is freed (~PySlaveInstance calls cleanPyObject, whose pointers were never cleared):
 * objects still in use are freed, or freed twice, and a later garbage collection crashes the host
 * (a pytest run after the FMU-state refusal tests: segfault "Garbage-collecting").  So the guard
 * forwards nothing more to an instance in the fatal state (every function's allowed states leave
 * it out), and fmi2FreeInstance frees only the guard's record (pythonfmu's C++ object, a few
 * hundred bytes, stays allocated; its Python objects were released once).  Our slaves give back
 * what pythonfmu releases (fmus/_inprocess.py), so their exceptions end in fmi2Error instead. */
EXPORT void fmi2FreeInstance(fmi2Component c) {
    if (c == NULL) return;
    GuardedInstance *in = guarded(c, "fmi2FreeInstance");
    if (in == NULL) return;
    save_signals(&in->signals);
    if (in->phase != PHASE_FATAL && real_fmi2FreeInstance != NULL) /* first: pythonfmu may log while freeing */
        ((void (*)(fmi2Component))real_fmi2FreeInstance)(in->real);
    if (real_fmi2FreeInstance != NULL) release_instance_objects(in);
    restore_signals(&in->signals);
    free_guarded(in);
    if (real_fmi2FreeInstance == NULL) return;
    lock(&load_lock);
    if (--live_instances == 0) release_pythonfmu_state();
    unlock(&load_lock);
}

#define CALL(name, params, ...) (((fmi2Status(*) params)real_##name)(in->real, __VA_ARGS__))
#define GUARDED(name, phases)                                                                                      \
    GuardedInstance *in = guarded(c, #name);                                                                       \
    if (in == NULL) return fmi2Error;                                                                              \
    if (!allowed_in(in, #name, phases)) return fmi2Error;                                                          \
    in->explained = in->recoverable = 0;
/* A call that is not on a step's path: the host's signal dispositions are put back after it (a
 * step's path, fmi2DoStep and fmi2Get/Set, pays nothing: Python's signal module was imported at
 * fmi2Instantiate, where they were put back, and no code of the FMU's sets a handler). */
#define KEEPING_HOST_SIGNALS(status, call)                                                                         \
    save_signals(&in->signals);                                                                                    \
    fmi2Status status = (call);                                                                                    \
    restore_signals(&in->signals);

/* Answered by the guard: pythonfmu's own logging stays on (see guard.h), the host's choice filters. */
EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String categories[]) {
    GUARDED(fmi2SetDebugLogging, PHASES_ANY_BUT_FATAL)
    return debug_logging(in, "fmi2SetDebugLogging", on != 0, n, categories);
}

EXPORT fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                                      fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    GUARDED(fmi2SetupExperiment, PHASE_INSTANTIATED)
    if (!isfinite(startTime)) REFUSE(in, "fmi2SetupExperiment", "startTime = %g is not finite", startTime);
    if (stopTimeDefined && !(isfinite(stopTime) && stopTime >= startTime))
        REFUSE(in, "fmi2SetupExperiment", "stopTime = %g is not a finite time >= startTime = %g", stopTime, startTime);
    KEEPING_HOST_SIGNALS(status, CALL(fmi2SetupExperiment,
                                      (fmi2Component, fmi2Boolean, fmi2Real, fmi2Real, fmi2Boolean, fmi2Real),
                                      toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime))
    if (status <= fmi2Warning) {
        in->time_known = 1;
        in->next_time = startTime;
        in->stop_defined = stopTimeDefined != 0;
        in->stop_time = stopTime;
    }
    return settle(in, "fmi2SetupExperiment", status, 0);
}

#define CALL_PLAIN(name) (((fmi2Status(*)(fmi2Component))real_##name)(in->real))

EXPORT fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    GUARDED(fmi2EnterInitializationMode, PHASE_INSTANTIATED)
    KEEPING_HOST_SIGNALS(status, CALL_PLAIN(fmi2EnterInitializationMode))
    return settle(in, "fmi2EnterInitializationMode", status, PHASE_INITIALIZATION);
}

EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    GUARDED(fmi2ExitInitializationMode, PHASE_INITIALIZATION)
    KEEPING_HOST_SIGNALS(status, CALL_PLAIN(fmi2ExitInitializationMode))
    return settle(in, "fmi2ExitInitializationMode", status, PHASE_STEP_COMPLETE);
}

EXPORT fmi2Status fmi2Terminate(fmi2Component c) {
    GUARDED(fmi2Terminate, PHASE_STEP_COMPLETE | PHASE_STEP_FAILED)
    KEEPING_HOST_SIGNALS(status, CALL_PLAIN(fmi2Terminate))
    return settle(in, "fmi2Terminate", status, PHASE_TERMINATED);
}

EXPORT fmi2Status fmi2Reset(fmi2Component c) {
    GUARDED(fmi2Reset, PHASES_ANY_BUT_FATAL)
    KEEPING_HOST_SIGNALS(status, CALL_PLAIN(fmi2Reset))
    if (status <= fmi2Warning) in->time_known = in->stop_defined = 0;
    return settle(in, "fmi2Reset", status, PHASE_INSTANTIATED);
}

/* fmi2Get<Type> and fmi2Set<Type>: the state, the arrays, every value reference (and for a set,
 * whether each variable may be set now); nothing is forwarded for nvr = 0. */
#define GET_SET(name, T, letter, phases, setting)                                                                  \
    EXPORT fmi2Status name(fmi2Component c, const fmi2ValueReference vr[], size_t n, T value[]) {                  \
        GUARDED(name, phases)                                                                                      \
        if (!references_ok(in, #name, vr, n, value, letter, setting)) return fmi2Error;                            \
        if (n == 0) return fmi2OK;                                                                                 \
        return settle(in, #name, CALL(name, (fmi2Component, const fmi2ValueReference[], size_t, T[]), vr, n, value), \
                      0);                                                                                          \
    }
GET_SET(fmi2GetReal, fmi2Real, 'R', PHASES_GET, 0)
GET_SET(fmi2GetInteger, fmi2Integer, 'I', PHASES_GET, 0)
GET_SET(fmi2GetBoolean, fmi2Boolean, 'B', PHASES_GET, 0)
GET_SET(fmi2GetString, fmi2String, 'S', PHASES_GET, 0)
GET_SET(fmi2SetReal, const fmi2Real, 'R', PHASES_SET, 1)
GET_SET(fmi2SetInteger, const fmi2Integer, 'I', PHASES_SET, 1)
GET_SET(fmi2SetBoolean, const fmi2Boolean, 'B', PHASES_SET, 1)
GET_SET(fmi2SetString, const fmi2String, 'S', PHASES_SET, 1)

/* FMU states: states.h. */
EXPORT fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state) {
    GUARDED(fmi2GetFMUstate, PHASES_ANY_BUT_FATAL)
    return get_state(in, "fmi2GetFMUstate", state, (Status(*)(void *, void **))real_fmi2GetFMUstate);
}

EXPORT fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) {
    GUARDED(fmi2SetFMUstate, PHASES_ANY_BUT_FATAL)
    return set_state(in, "fmi2SetFMUstate", state, (Status(*)(void *, void *))real_fmi2SetFMUstate);
}

EXPORT fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    GUARDED(fmi2FreeFMUstate, PHASES_ANY_BUT_FATAL)
    return free_state(in, "fmi2FreeFMUstate", state);
}

EXPORT fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size) {
    GUARDED(fmi2SerializedFMUstateSize, PHASES_ANY_BUT_FATAL)
    return serialized_state_size(in, "fmi2SerializedFMUstateSize", state, size);
}

EXPORT fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte bytes[], size_t size) {
    GUARDED(fmi2SerializeFMUstate, PHASES_ANY_BUT_FATAL)
    return serialize_state(in, "fmi2SerializeFMUstate", state, bytes, size);
}

EXPORT fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[], size_t size, fmi2FMUstate *state) {
    GUARDED(fmi2DeSerializeFMUstate, PHASES_ANY_BUT_FATAL)
    return deserialize_state(in, "fmi2DeSerializeFMUstate", bytes, size, state);
}

/* The functions pythonfmu does not support (it says so and returns fmi2Error or fmi2Discard):
 * the state is checked, the answer changes nothing. */
EXPORT fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference unknown[], size_t nUnknown,
                                               const fmi2ValueReference known[], size_t nKnown,
                                               const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    GUARDED(fmi2GetDirectionalDerivative, PHASES_GET)
    return answered(in, "fmi2GetDirectionalDerivative", CALL(fmi2GetDirectionalDerivative,
                (fmi2Component, const fmi2ValueReference[], size_t, const fmi2ValueReference[], size_t,
                 const fmi2Real[], fmi2Real[]),
                unknown, nUnknown, known, nKnown, dvKnown, dvUnknown));
}

EXPORT fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                              const fmi2Integer order[], const fmi2Real value[]) {
    GUARDED(fmi2SetRealInputDerivatives, PHASES_SET)
    return answered(in, "fmi2SetRealInputDerivatives", CALL(fmi2SetRealInputDerivatives,
                (fmi2Component, const fmi2ValueReference[], size_t, const fmi2Integer[], const fmi2Real[]), vr, n,
                order, value));
}

EXPORT fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                               const fmi2Integer order[], fmi2Real value[]) {
    GUARDED(fmi2GetRealOutputDerivatives, PHASES_OUTPUT_DERIVATIVES)
    return answered(in, "fmi2GetRealOutputDerivatives", CALL(fmi2GetRealOutputDerivatives,
                (fmi2Component, const fmi2ValueReference[], size_t, const fmi2Integer[], fmi2Real[]), vr, n, order,
                value));
}

EXPORT fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                             fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    GUARDED(fmi2DoStep, PHASE_STEP_COMPLETE)
    double t = currentCommunicationPoint, h = communicationStepSize;
    if (!isfinite(t)) REFUSE(in, "fmi2DoStep", "currentCommunicationPoint = %g is not finite", t);
    if (!(isfinite(h) && h > 0))
        REFUSE(in, "fmi2DoStep", "communicationStepSize = %g: a step must be finite and > 0", h);
    if (in->model.max_step > 0 && h > in->model.max_step)
        REFUSE(in, "fmi2DoStep",
               "communicationStepSize = %g s is longer than this FMU's longest step, %g s (10^4 DefaultExperiment "
               "steps: the FMU computes every internal sample of a step)",
               h, in->model.max_step);
    if (!isfinite(t + h)) REFUSE(in, "fmi2DoStep", "currentCommunicationPoint + communicationStepSize is not finite");
    if (in->time_known && !same_time(t, in->next_time))
        REFUSE(in, "fmi2DoStep",
               "currentCommunicationPoint = %.17g s, but the instance is at %.17g s (a step starts where the last one "
               "ended; fmi2SetFMUstate moves the time)",
               t, in->next_time);
    if (in->stop_defined && t + h > in->stop_time && !same_time(t + h, in->stop_time))
        REFUSE(in, "fmi2DoStep", "the step [%.17g, %.17g] s ends after stopTime = %.17g s (fmi2SetupExperiment)", t,
               t + h, in->stop_time);
    fmi2Status status =
        CALL(fmi2DoStep, (fmi2Component, fmi2Real, fmi2Real, fmi2Boolean), t, h, noSetFMUStatePriorToCurrentPoint);
    if (status <= fmi2Warning) {
        in->time_known = 1;
        in->next_time = t + h;
    }
    return settle(in, "fmi2DoStep", status, status == fmi2Discard ? PHASE_STEP_FAILED : PHASE_STEP_COMPLETE);
}

EXPORT fmi2Status fmi2CancelStep(fmi2Component c) {
    GUARDED(fmi2CancelStep, 0) /* no step is ever in progress: fmi2DoStep is synchronous */
    return fmi2Error;
}

#define STATUS_INQUIRY(name, T)                                                                                    \
    EXPORT fmi2Status name(fmi2Component c, const fmi2StatusKind s, T *value) {                                    \
        GUARDED(name, PHASES_STATUS)                                                                               \
        if (value == NULL) REFUSE(in, #name, "value (where to write the status) is NULL");                         \
        return answered(in, #name, CALL(name, (fmi2Component, const fmi2StatusKind, T *), s, value));             \
    }
STATUS_INQUIRY(fmi2GetStatus, fmi2Status)
STATUS_INQUIRY(fmi2GetRealStatus, fmi2Real)
STATUS_INQUIRY(fmi2GetIntegerStatus, fmi2Integer)
STATUS_INQUIRY(fmi2GetBooleanStatus, fmi2Boolean)
STATUS_INQUIRY(fmi2GetStringStatus, fmi2String)

/* Unload: pythonfmu's state released (see the top comment), then its library (Linux only:
 * Windows forbids unloading a DLL while one is being detached); Windows: this loader's handles
 * of the process-wide lock closed. */
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
