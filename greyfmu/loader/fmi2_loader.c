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
 *      initialised without signal handlers (Py_InitializeEx(0); on Linux with PYTHONHOME set for
 *      the call only, Windows finds the home from the DLL), given the candidate's sys.path
 *      (venv site-packages included) and sys.executable; the GIL is then released.
 *   3. The same greyfmu_target.py runs inside the process (Python version >= 3.10 and the
 *      requirements; once per process, see CHECK_ONCE), then pythonfmu-export.so is loaded and
 *      every fmi2 function forwards to it.
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

/* ---- the few Python C-API functions the loader calls, resolved with dlsym ---- */
typedef struct {
    int (*IsInitialized)(void);
    void (*InitializeEx)(int);
    void *(*EvalSaveThread)(void);
    int (*GILStateEnsure)(void);
    void (*GILStateRelease)(int);
    void *(*DictNew)(void);
    int (*DictSetItemString)(void *, const char *, void *);
    void *(*DictGetItemString)(void *, const char *);
    void *(*EvalGetBuiltins)(void);
    void *(*RunStringFlags)(const char *, int, void *, void *, void *);
    void *(*UnicodeFromString)(const char *);
    const char *(*UnicodeAsUTF8)(void *);
    void (*DecRef)(void *);
    void (*ErrPrint)(void);
} PythonApi;

enum { PY_FILE_INPUT = 257 };

static Lock load_lock = LOCK_INITIALIZER;
static void *pythonfmu_library;
static PythonApi python_api;       /* the Python pythonfmu's library runs on, once loaded */
static char resources[PATH_MAX + 16]; /* this FMU's resources folder, found from this binary */
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

/* ---- small helpers ---- */

/* The FMU's root folder: this library is <root>/binaries/<platform>/<id>.<suffix>. */
static int fmu_root(char *root, size_t size) {
    char path[PATH_MAX];
    if (!library_path(path, sizeof path)) return 0;
    for (int level = 0; level < 3; level++) {
        char *separator = strrchr(path, SEPARATOR);
        if (separator == NULL) return 0;
        *separator = '\0';
    }
    snprintf(root, size, "%s", path);
    return 1;
}

static char *read_file(const char *path) {
    FILE *file = fopen(path, "rb");
    if (file == NULL) return NULL;
    size_t capacity = 4096, length = 0;
    char *text = malloc(capacity);
    size_t got;
    while (text != NULL && (got = fread(text + length, 1, capacity - length - 1, file)) > 0) {
        length += got;
        if (length + 1 == capacity) {
            char *grown = realloc(text, capacity *= 2);
            if (grown == NULL) free(text);
            text = grown;
        }
    }
    fclose(file);
    if (text != NULL) text[length] = '\0';
    return text;
}

/* python3 (Windows: python.exe) on PATH, as a shell would find it. */
static int python_on_path(char *found, size_t size) {
    const char *path = getenv("PATH");
    while (path != NULL && *path) {
        size_t length = strcspn(path, PATH_LIST_SEPARATOR);
        snprintf(found, size, "%.*s%c%s", (int)(length ? length : 1), length ? path : ".", SEPARATOR, PYTHON_ON_PATH);
        if (is_executable(found)) return 1;
        path += length + (path[length] ? 1 : 0);
    }
    return 0;
}

/* The value of "greyfmu-<key>=" in the query output, copied into value; 0 if absent. */
static int query_value(const char *output, const char *key, char *value, size_t size) {
    char marker[64];
    snprintf(marker, sizeof marker, "greyfmu-%s=", key);
    const char *line = output;
    while ((line = strstr(line, marker)) != NULL) {
        if (line == output || line[-1] == '\n') {
            line += strlen(marker);
            size_t length = strcspn(line, "\r\n");
            if (length >= size) length = size - 1;
            memcpy(value, line, length);
            value[length] = '\0';
            return 1;
        }
        line += strlen(marker);
    }
    return 0;
}

/* What the check script reports of a usable candidate interpreter. */
typedef struct {
    char executable[PATH_MAX]; /* its sys.executable (a wrapper script or shim resolved) */
    char libpython[PATH_MAX];
    char stable_abi[PATH_MAX]; /* Windows: python3.dll next to pythonXY.dll, which pythonfmu's DLL imports */
    char home[2 * PATH_MAX];   /* PYTHONHOME: base prefix (and base exec prefix) */
    char *path;                /* repr(sys.path), malloc'ed */
} Interpreter;

/* Query a candidate interpreter; 0 with problem set if it is unusable. */
static int query_candidate(const char *python, const char *root, Interpreter *found, char *problem, size_t size) {
    char script[PATH_MAX + 64];
    snprintf(script, sizeof script, "%s%cresources%cgreyfmu_target.py", root, SEPARATOR, SEPARATOR);
    char *output = NULL;
    if (!run_query(python, script, &output, problem, size)) return 0;
    char answer[4096];
    int ok = 0;
    if (!query_value(output, "problem", answer, sizeof answer)) {
        append(problem, size, "%s did not run the check %s: %.600s", python, script, output);
    } else if (answer[0] != '\0') {
        append(problem, size, "%s", answer);
    } else if (query_value(output, "executable", found->executable, sizeof found->executable) &&
               query_value(output, "libpython", found->libpython, sizeof found->libpython) &&
               query_value(output, "stable_abi", found->stable_abi, sizeof found->stable_abi) &&
               query_value(output, "home", found->home, sizeof found->home)) {
        char *line = strstr(output, "greyfmu-path=");
        if (line != NULL) {
            size_t length = strcspn(line + 13, "\r\n");
            if ((found->path = malloc(length + 1)) != NULL) {
                memcpy(found->path, line + 13, length);
                found->path[length] = '\0';
            }
        }
        ok = found->path != NULL;
    }
    if (!ok && !*problem) append(problem, size, "%s gave an incomplete answer to %s: %.600s", python, script, output);
    free(output);
    return ok;
}

static int resolve(void *library, PythonApi *api, char *problem, size_t size) {
#define RESOLVE(field, symbol)                                                                                     \
    if ((*(void **)&api->field = library_symbol(library, symbol)) == NULL) {                                      \
        append(problem, size, "the loaded libpython has no %s", symbol);                                          \
        return 0;                                                                                                  \
    }
    RESOLVE(IsInitialized, "Py_IsInitialized")
    RESOLVE(InitializeEx, "Py_InitializeEx")
    RESOLVE(EvalSaveThread, "PyEval_SaveThread")
    RESOLVE(GILStateEnsure, "PyGILState_Ensure")
    RESOLVE(GILStateRelease, "PyGILState_Release")
    RESOLVE(DictNew, "PyDict_New")
    RESOLVE(DictSetItemString, "PyDict_SetItemString")
    RESOLVE(DictGetItemString, "PyDict_GetItemString")
    RESOLVE(EvalGetBuiltins, "PyEval_GetBuiltins")
    RESOLVE(RunStringFlags, "PyRun_StringFlags")
    RESOLVE(UnicodeFromString, "PyUnicode_FromString")
    RESOLVE(UnicodeAsUTF8, "PyUnicode_AsUTF8")
    RESOLVE(DecRef, "Py_DecRef")
    RESOLVE(ErrPrint, "PyErr_Print")
#undef RESOLVE
    return 1;
}

/* Run code in a fresh namespace under the GIL; the string variable `result_name` it leaves, copied. */
static int run_in_process(PythonApi *api, const char *code, const char *file, const char *result_name, char *result,
                          size_t size) {
    int gil = api->GILStateEnsure();
    void *globals = api->DictNew();
    api->DictSetItemString(globals, "__builtins__", api->EvalGetBuiltins());
    void *name = api->UnicodeFromString("greyfmu_target");
    api->DictSetItemString(globals, "__name__", name);
    api->DecRef(name);
    void *file_name = api->UnicodeFromString(file);
    api->DictSetItemString(globals, "__file__", file_name);
    api->DecRef(file_name);
    void *done = api->RunStringFlags(code, PY_FILE_INPUT, globals, globals, NULL);
    int ok = done != NULL;
    if (ok) {
        api->DecRef(done);
        void *value = result_name ? api->DictGetItemString(globals, result_name) : NULL;
        const char *text = value ? api->UnicodeAsUTF8(value) : "";
        snprintf(result, size, "%s", text ? text : "");
    } else {
        api->ErrPrint();
        snprintf(result, size, "running %s inside the host process raised a Python exception (printed on stderr)", file);
    }
    api->DecRef(globals);
    api->GILStateRelease(gil);
    return ok;
}

/* A Python literal of a path (the check script's sys.executable assignment). */
static void python_literal(const char *text, char *literal, size_t size) {
    snprintf(literal, size, "'");
    for (const char *c = text; *c; c++) {
        if (*c == '\\' || *c == '\'') append(literal, size, "\\");
        append(literal, size, "%c", *c);
    }
    append(literal, size, "'");
}

/* Start the candidate's Python in this process. */
static int start_python(const Interpreter *python, PythonApi *api, char *problem, size_t size) {
    void *library = library_open(python->libpython, 1, problem, size);
    if (library == NULL) {
        append(problem, size, " (the shared libpython of %s)", python->executable);
        return 0;
    }
    if (*python->stable_abi && library_open(python->stable_abi, 1, problem, size) == NULL) return 0;
    if (!resolve(library, api, problem, size)) return 0;
    if (!api->IsInitialized()) {
        char *saved = set_python_home(python->home);
        api->InitializeEx(0);
        restore_python_home(saved);
        char executable[2 * PATH_MAX];
        python_literal(python->executable, executable, sizeof executable);
        size_t length = strlen(python->path) + strlen(executable) + 128;
        char *code = malloc(length);
        snprintf(code, length, "import sys\nsys.path[:] = %s\nsys.executable = %s\n", python->path, executable);
        char ignored[16];
        int ok = run_in_process(api, code, "<greyfmu loader>", NULL, ignored, sizeof ignored);
        free(code);
        api->EvalSaveThread(); /* Python stays initialised; pythonfmu takes the GIL per call */
        if (!ok) {
            append(problem, size, "cannot set sys.path of %s inside the host process", python->executable);
            return 0;
        }
    }
    return 1;
}


/* Find, load and initialise a Python in this process, unless it already runs one.  Never a second
 * libpython: one already loaded but not initialised is initialised, if it is the candidate's. */
static int ensure_python(const char *root, PythonApi *api, char *problem, size_t size) {
    void *host_python = loaded_python();
    if (host_python != NULL) {
        if (!resolve(host_python, api, problem, size)) return 0;
        if (api->IsInitialized()) return 1;
    }

    char candidates[3][PATH_MAX];
    const char *origin[3];
    int count = 0;
    const char *chosen = getenv("GREYFMU_PYTHON");
    if (chosen != NULL && *chosen) {
        snprintf(candidates[count], PATH_MAX, "%s", chosen);
        origin[count++] = "GREYFMU_PYTHON";
    } else {
        char file[PATH_MAX + 64];
        snprintf(file, sizeof file, "%s%cresources%cgreyfmu_build_python.txt", root, SEPARATOR, SEPARATOR);
        char *built_by = read_file(file);
        if (built_by != NULL) {
            built_by[strcspn(built_by, "\r\n")] = '\0';
            if (is_executable(built_by)) {
                snprintf(candidates[count], PATH_MAX, "%s", built_by);
                origin[count++] = "the interpreter that built the FMU";
            }
            free(built_by);
        }
        if (python_on_path(candidates[count], PATH_MAX)) origin[count++] = PYTHON_ON_PATH " on PATH";
    }
    if (count == 0) {
        append(problem, size, "no Python found: GREYFMU_PYTHON is not set, the interpreter that built the FMU is not on "
                              "this machine and there is no " PYTHON_ON_PATH " on PATH");
        return 0;
    }
    char tried[8192] = "";
    for (int i = 0; i < count; i++) {
        if (!is_executable(candidates[i])) {
            append(tried, sizeof tried, "%s%s (%s) is not an executable file", *tried ? "; " : "", candidates[i],
                   origin[i]);
            continue;
        }
        Interpreter found = {.path = NULL};
        char why[4096] = "";
        if (query_candidate(candidates[i], root, &found, why, sizeof why)) {
            int ok = host_python == NULL || is_loaded_python(host_python, found.libpython);
            if (!ok)
                append(problem, size, "this process already has a libpython, not initialised, that is not %s's (%s): "
                       "set GREYFMU_PYTHON to the Python of the host's libpython", found.executable, found.libpython);
            ok = ok && start_python(&found, api, problem, size);
            free(found.path);
            return ok;
        }
        append(tried, sizeof tried, "%s%s (%s): %s", *tried ? "; " : "", candidates[i], origin[i], why);
    }
    append(problem, size, "no usable Python: %s", tried);
    return 0;
}

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

/* Runs resources/greyfmu_target.py (its path is __file__) inside the process and leaves its
 * `problem`, at most once per process for the same script and requirements: a passed check is
 * remembered in sys.modules["greyfmu_target_checks"] (this library's statics die when a host
 * such as fmpy unloads it after each instance), so a re-instantiation does not compile the
 * script again.  The key is the two files' text, so another FMU or another version of one is
 * checked anew; a pass stays valid, as the modules it imported stay in sys.modules. */
static const char CHECK_ONCE[] =
    "import os, sys\n"
    "checks = sys.modules.get('greyfmu_target_checks')\n"
    "if checks is None:\n"
    "    checks = sys.modules['greyfmu_target_checks'] = type(sys)('greyfmu_target_checks')\n"
    "    checks.passed = set()\n"
    "with open(__file__, 'rb') as script:\n"
    "    source = script.read()\n"
    "with open(os.path.join(os.path.dirname(__file__), 'greyfmu_requirements.txt'), 'rb') as listing:\n"
    "    key = (source, listing.read())\n"
    "problem = ''\n"
    "if key not in checks.passed:\n"
    "    namespace = {'__name__': 'greyfmu_target', '__file__': __file__, '__builtins__': __builtins__}\n"
    "    exec(compile(source, __file__, 'exec'), namespace)\n"
    "    problem = namespace['problem']\n"
    "    if not problem:\n"
    "        checks.passed.add(key)\n";

static int ensure_loaded(char *problem, size_t size) {
    if (pythonfmu_library != NULL) return 1;
    char root[PATH_MAX];
    if (!fmu_root(root, sizeof root)) {
        append(problem, size, "cannot locate the FMU's folder from its binary");
        return 0;
    }
    PythonApi api;
    if (!ensure_python(root, &api, problem, size)) return 0;
    char script[PATH_MAX + 64];
    snprintf(script, sizeof script, "%s%cresources%cgreyfmu_target.py", root, SEPARATOR, SEPARATOR);
    char answer[4096];
    run_in_process(&api, CHECK_ONCE, script, "problem", answer, sizeof answer);
    if (answer[0] != '\0') {
        append(problem, size, "%s", answer);
        return 0;
    }
    if (!load_pythonfmu(root, problem, size)) return 0;
    python_api = api;
    snprintf(resources, sizeof resources, "%s%cresources", root, SEPARATOR);
    return 1;
}

/* Gives back the reference pythonfmu 0.7.0's fmi2Instantiate takes from the process at each call
 * (PySlaveInstance.cpp): findClass releases the slave module's __dict__, a borrowed reference (PyModule_GetDict),
 *     once per instantiation that got as far as importing the module: after as many
 *     instantiations as the dict has holders, the dict is freed while its module still uses it
 *     and the next garbage collection crashes the host (a pytest run of 1,400 tests: segfault
 *     "Garbage-collecting" in DigitalPI).  One reference per instantiation is kept in
 *     sys.modules["greyfmu_target_checks"].released (8 bytes each); where the module was
 *     imported but the dict not released (a failure in between), one dict stays alive forever,
 *     which it does anyway as its module is in sys.modules.
 * Runs after every forwarded fmi2Instantiate, whether it returned an instance or not. */
static const char BALANCE_PYTHONFMU[] =
    "import os, sys\n"
    "checks = sys.modules.get('greyfmu_target_checks')\n"
    "if checks is None:\n"
    "    checks = sys.modules['greyfmu_target_checks'] = type(sys)('greyfmu_target_checks')\n"
    "    checks.passed = set()\n"
    "if not hasattr(checks, 'released'):\n"
    "    checks.released = []\n"
    "with open(os.path.join(os.path.dirname(__file__), 'slavemodule.txt'), encoding='utf-8') as listing:\n"
    "    module = sys.modules.get(listing.readline().strip())\n"
    "if module is not None:\n"
    "    checks.released.append(module.__dict__)\n";

static void balance_pythonfmu(void) {
    char script[PATH_MAX + 64], ignored[256];
    snprintf(script, sizeof script, "%s%cgreyfmu_balance", resources, SEPARATOR);
    run_in_process(&python_api, BALANCE_PYTHONFMU, script, NULL, ignored, sizeof ignored);
}

/* ---- instances pythonfmu has given up on ----
 * pythonfmu 0.7.0 answers a Python exception in any call with fmi2Fatal after releasing the
 * instance's Python objects (PySlaveInstance.cpp: handle_py_exception calls cleanPyObject), and
 * releases them again when the instance is freed (~PySlaveInstance calls cleanPyObject, whose
 * pointers were never cleared): objects still in use are freed, or freed twice, and a later
 * garbage collection crashes the host (a pytest run after the FMU-state refusal tests: segfault
 * "Garbage-collecting").  The loader remembers each instance that answered fmi2Fatal: nothing
 * more is forwarded to it (fmi2Error), and fmi2FreeInstance forgets it without forwarding (its
 * C++ object, a few hundred bytes, stays allocated; its Python objects were released once). */
static fmi2Component *lost_instances;
static size_t lost_count, lost_capacity;

static int is_lost(fmi2Component c) {
    int found = 0;
    lock(&load_lock);
    for (size_t i = 0; i < lost_count && !found; i++) found = lost_instances[i] == c;
    unlock(&load_lock);
    return found;
}

static void remember_lost(fmi2Component c) {
    lock(&load_lock);
    if (lost_count == lost_capacity) {
        size_t capacity = lost_capacity ? 2 * lost_capacity : 8;
        fmi2Component *grown = realloc(lost_instances, capacity * sizeof *grown);
        if (grown != NULL) {
            lost_instances = grown;
            lost_capacity = capacity;
        }
    }
    if (lost_count < lost_capacity) lost_instances[lost_count++] = c;
    unlock(&load_lock);
}

/* Whether `c` was lost; if so it is forgotten (its fmi2FreeInstance). */
static int forget_lost(fmi2Component c) {
    int found = 0;
    lock(&load_lock);
    for (size_t i = 0; i < lost_count && !found; i++)
        if (lost_instances[i] == c) {
            lost_instances[i] = lost_instances[--lost_count];
            found = 1;
        }
    unlock(&load_lock);
    return found;
}

/* ---- the exported FMI 2.0 functions ---- */

EXPORT const char *fmi2GetTypesPlatform(void) { return "default"; }

EXPORT const char *fmi2GetVersion(void) { return "2.0"; }

EXPORT fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                                     fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                                     fmi2Boolean visible, fmi2Boolean loggingOn) {
    char problem[16384] = "";
    lock(&load_lock);
    int loaded = ensure_loaded(problem, sizeof problem);
    unlock(&load_lock);
    if (!loaded) {
        if (functions != NULL && functions->logger != NULL)
            functions->logger(functions->componentEnvironment, instanceName, fmi2Error, "logStatusError",
                              "greyfmu: %s", problem);
        else
            fprintf(stderr, "greyfmu: %s\n", problem);
        return NULL;
    }
    typedef fmi2Component (*Instantiate)(fmi2String, fmi2Type, fmi2String, fmi2String, const fmi2CallbackFunctions *,
                                         fmi2Boolean, fmi2Boolean);
    fmi2Component component =
        ((Instantiate)real_fmi2Instantiate)(instanceName, fmuType, fmuGUID, fmuResourceLocation, functions, visible,
                                            loggingOn);
    balance_pythonfmu();
    if (component != NULL) {
        lock(&load_lock);
        live_instances++;
        unlock(&load_lock);
    }
    return component;
}

EXPORT void fmi2FreeInstance(fmi2Component c) {
    if (real_fmi2FreeInstance == NULL || c == NULL) return;
    if (!forget_lost(c)) ((void (*)(fmi2Component))real_fmi2FreeInstance)(c);
    lock(&load_lock);
    if (--live_instances == 0) release_pythonfmu_state();
    unlock(&load_lock);
}

#define FORWARD(ret, name, params, args)                                                                           \
    EXPORT ret name params {                                                                                       \
        if (real_##name == NULL || is_lost(c)) return fmi2Error;                                                   \
        ret status = ((ret(*) params)real_##name) args;                                                            \
        if (status == fmi2Fatal) remember_lost(c);                                                                 \
        return status;                                                                                             \
    }

FORWARD(fmi2Status, fmi2SetDebugLogging, (fmi2Component c, fmi2Boolean on, size_t n, const fmi2String categories[]),
        (c, on, n, categories))
FORWARD(fmi2Status, fmi2SetupExperiment,
        (fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance, fmi2Real startTime,
         fmi2Boolean stopTimeDefined, fmi2Real stopTime),
        (c, toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime))
FORWARD(fmi2Status, fmi2EnterInitializationMode, (fmi2Component c), (c))
FORWARD(fmi2Status, fmi2ExitInitializationMode, (fmi2Component c), (c))
FORWARD(fmi2Status, fmi2Terminate, (fmi2Component c), (c))
FORWARD(fmi2Status, fmi2Reset, (fmi2Component c), (c))
FORWARD(fmi2Status, fmi2GetReal, (fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real value[]),
        (c, vr, n, value))
FORWARD(fmi2Status, fmi2GetInteger, (fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer value[]),
        (c, vr, n, value))
FORWARD(fmi2Status, fmi2GetBoolean, (fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean value[]),
        (c, vr, n, value))
FORWARD(fmi2Status, fmi2GetString, (fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String value[]),
        (c, vr, n, value))
FORWARD(fmi2Status, fmi2SetReal, (fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real value[]),
        (c, vr, n, value))
FORWARD(fmi2Status, fmi2SetInteger,
        (fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer value[]), (c, vr, n, value))
FORWARD(fmi2Status, fmi2SetBoolean,
        (fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean value[]), (c, vr, n, value))
FORWARD(fmi2Status, fmi2SetString,
        (fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String value[]), (c, vr, n, value))
FORWARD(fmi2Status, fmi2GetFMUstate, (fmi2Component c, fmi2FMUstate *state), (c, state))
FORWARD(fmi2Status, fmi2SetFMUstate, (fmi2Component c, fmi2FMUstate state), (c, state))
FORWARD(fmi2Status, fmi2FreeFMUstate, (fmi2Component c, fmi2FMUstate *state), (c, state))
FORWARD(fmi2Status, fmi2SerializedFMUstateSize, (fmi2Component c, fmi2FMUstate state, size_t *size), (c, state, size))
FORWARD(fmi2Status, fmi2SerializeFMUstate, (fmi2Component c, fmi2FMUstate state, fmi2Byte bytes[], size_t size),
        (c, state, bytes, size))
FORWARD(fmi2Status, fmi2DeSerializeFMUstate,
        (fmi2Component c, const fmi2Byte bytes[], size_t size, fmi2FMUstate *state), (c, bytes, size, state))
FORWARD(fmi2Status, fmi2GetDirectionalDerivative,
        (fmi2Component c, const fmi2ValueReference unknown[], size_t nUnknown, const fmi2ValueReference known[],
         size_t nKnown, const fmi2Real dvKnown[], fmi2Real dvUnknown[]),
        (c, unknown, nUnknown, known, nKnown, dvKnown, dvUnknown))
FORWARD(fmi2Status, fmi2SetRealInputDerivatives,
        (fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer order[], const fmi2Real value[]),
        (c, vr, n, order, value))
FORWARD(fmi2Status, fmi2GetRealOutputDerivatives,
        (fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer order[], fmi2Real value[]),
        (c, vr, n, order, value))
FORWARD(fmi2Status, fmi2DoStep,
        (fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
         fmi2Boolean noSetFMUStatePriorToCurrentPoint),
        (c, currentCommunicationPoint, communicationStepSize, noSetFMUStatePriorToCurrentPoint))
FORWARD(fmi2Status, fmi2CancelStep, (fmi2Component c), (c))
FORWARD(fmi2Status, fmi2GetStatus, (fmi2Component c, const fmi2StatusKind s, fmi2Status *value), (c, s, value))
FORWARD(fmi2Status, fmi2GetRealStatus, (fmi2Component c, const fmi2StatusKind s, fmi2Real *value), (c, s, value))
FORWARD(fmi2Status, fmi2GetIntegerStatus, (fmi2Component c, const fmi2StatusKind s, fmi2Integer *value),
        (c, s, value))
FORWARD(fmi2Status, fmi2GetBooleanStatus, (fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value),
        (c, s, value))
FORWARD(fmi2Status, fmi2GetStringStatus, (fmi2Component c, const fmi2StatusKind s, fmi2String *value),
        (c, s, value))

/* Unload: pythonfmu's state released (see the top comment), then its library (Linux only:
 * Windows forbids unloading a DLL while one is being detached). */
#ifndef _WIN32
__attribute__((destructor)) static void unload_loader(void) {
    if (pythonfmu_library == NULL || live_instances > 0) return;
    release_pythonfmu_state();
    dlclose(pythonfmu_library);
    pythonfmu_library = NULL;
}
#endif
