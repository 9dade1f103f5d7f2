/* The Python of the greyfmu loaders (fmi2_loader.c, fmi3_loader.c): finding a Python, starting it
 * in the host process once per process, running code in it, and the check before each
 * instantiation.  fmi2_loader.c's top comment says how a Python is chosen and started.
 *
 * Before including it a loader includes platform.h; it defines `resources` (this FMU's resources
 * folder) and `python_api` (the Python the FMU's code runs on) for guard.h and states.h.
 */
#ifndef GREYFMU_LOADER_PYTHON_H
#define GREYFMU_LOADER_PYTHON_H
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
    void *(*UnicodeDecodeFSDefault)(const char *);
    void *(*UnicodeEncodeFSDefault)(void *);
    char *(*BytesAsString)(void *);
    void (*DecRef)(void *);
    void (*IncRef)(void *);
    void (*ErrPrint)(void);
    void *(*GetAttrString)(void *, const char *);
    void *(*CallFunctionObjArgs)(void *, ...);
    void *(*BytesFromStringAndSize)(const char *, intptr_t); /* Py_ssize_t */
    int (*BytesAsStringAndSize)(void *, char **, intptr_t *);
    void (*ErrFetch)(void **, void **, void **);
    void *(*ObjectStr)(void *);
} PythonApi;

enum { PY_FILE_INPUT = 257 };

static Lock load_lock = LOCK_INITIALIZER;
static PythonApi python_api;          /* the Python the FMU's library runs on, once loaded */
static char resources[PATH_MAX + 16]; /* this FMU's resources folder, found from this binary */

/* ---- small helpers ---- */

/* The FMU's root folder: this library is <root>/binaries/<platform>/<id>.<suffix>. */
static int fmu_root(char *root, size_t size) {
    if (!library_path(root, size)) return 0;
    for (int level = 0; level < 3; level++) {
        char *separator = strrchr(root, SEPARATOR);
        if (separator == NULL) return 0;
        *separator = '\0';
    }
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
    struct {
        char script[PATH_MAX + 64], answer[4096];
    } *scratch = malloc(sizeof *scratch); /* on the heap, as every large buffer of fmi2Instantiate */
    if (scratch == NULL) {
        append(problem, size, "out of memory querying %s", python);
        return 0;
    }
    char *script = scratch->script, *answer = scratch->answer;
    snprintf(script, sizeof scratch->script, "%s%cresources%cgreyfmu_target.py", root, SEPARATOR, SEPARATOR);
    char *output = NULL;
    if (!run_query(python, script, &output, problem, size)) {
        free(scratch);
        return 0;
    }
    int ok = 0;
    if (!query_value(output, "problem", answer, sizeof scratch->answer)) {
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
            } else {
                append(problem, size, "out of memory reading the answer of %s", python);
            }
        }
        ok = found->path != NULL;
    }
    if (!ok && !*problem) append(problem, size, "%s gave an incomplete answer to %s: %.600s", python, script, output);
    free(output);
    free(scratch);
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
    RESOLVE(UnicodeDecodeFSDefault, "PyUnicode_DecodeFSDefault")
    RESOLVE(UnicodeEncodeFSDefault, "PyUnicode_EncodeFSDefault")
    RESOLVE(BytesAsString, "PyBytes_AsString")
    RESOLVE(DecRef, "Py_DecRef")
    RESOLVE(IncRef, "Py_IncRef")
    RESOLVE(ErrPrint, "PyErr_Print")
    RESOLVE(GetAttrString, "PyObject_GetAttrString")
    RESOLVE(CallFunctionObjArgs, "PyObject_CallFunctionObjArgs")
    RESOLVE(BytesFromStringAndSize, "PyBytes_FromStringAndSize")
    RESOLVE(BytesAsStringAndSize, "PyBytes_AsStringAndSize")
    RESOLVE(ErrFetch, "PyErr_Fetch")
    RESOLVE(ObjectStr, "PyObject_Str")
#undef RESOLVE
    return 1;
}

/* A str variable given to or taken from code run inside the process, as the file system's bytes. */
typedef struct {
    const char *name;
    char *text;  /* given: its value; taken: where it is copied ("" if the code left none) */
    size_t size; /* 0: given; else the size of `text` */
} PyVariable;

/* The str variable v->name of `globals` ("" if absent) copied into v->text; 0 with a Python
 * exception set if it is not a str. */
static int take_variable(PythonApi *api, void *globals, PyVariable *v) {
    v->text[0] = '\0';
    void *value = api->DictGetItemString(globals, v->name); /* borrowed */
    if (value == NULL) return 1;
    void *bytes = api->UnicodeEncodeFSDefault(value);
    const char *text = bytes != NULL ? api->BytesAsString(bytes) : NULL;
    if (text != NULL) snprintf(v->text, v->size, "%s", text);
    api->DecRef(bytes); /* Py_DecRef is Py_XDECREF */
    return text != NULL;
}

/* Run code in a fresh namespace under the GIL, `file` as its __file__, with `variables` given
 * to it (size 0) and taken from it (size > 0), then `inspect(api, globals, context)` if given.
 * 0 (the exception printed on stderr) if any step fails, Python's own calls included. */
static int run_in_process(PythonApi *api, const char *code, const char *file, PyVariable *variables, int count,
                          void (*inspect)(PythonApi *, void *, void *), void *context) {
    int gil = api->GILStateEnsure();
    void *globals = api->DictNew(), *builtins = api->EvalGetBuiltins(); /* builtins: borrowed */
    void *name = api->UnicodeFromString("greyfmu_target"), *file_name = api->UnicodeDecodeFSDefault(file);
    int ok = globals != NULL && builtins != NULL && name != NULL && file_name != NULL &&
             api->DictSetItemString(globals, "__builtins__", builtins) == 0 &&
             api->DictSetItemString(globals, "__name__", name) == 0 &&
             api->DictSetItemString(globals, "__file__", file_name) == 0;
    for (int i = 0; ok && i < count; i++) {
        if (variables[i].size > 0) continue;
        void *value = api->UnicodeDecodeFSDefault(variables[i].text);
        ok = value != NULL && api->DictSetItemString(globals, variables[i].name, value) == 0;
        api->DecRef(value);
    }
    void *done = ok ? api->RunStringFlags(code, PY_FILE_INPUT, globals, globals, NULL) : NULL;
    ok = done != NULL;
    for (int i = 0; ok && i < count; i++)
        if (variables[i].size > 0) ok = take_variable(api, globals, &variables[i]);
    if (ok && inspect != NULL) inspect(api, globals, context);
    if (!ok) api->ErrPrint();
    api->DecRef(done);
    api->DecRef(file_name);
    api->DecRef(name);
    api->DecRef(globals);
    api->GILStateRelease(gil);
    return ok;
}

/* A Python bytes literal of a path, every byte outside printable ASCII escaped (the path need not
 * be UTF-8); `literal` holds 4 * strlen(text) + 4 bytes. */
static void bytes_literal(const char *text, char *literal, size_t size) {
    size_t used = (size_t)snprintf(literal, size, "b'");
    for (const unsigned char *c = (const unsigned char *)text; *c && used + 5 < size; c++) {
        if (*c < 0x20 || *c >= 0x7f || *c == '\\' || *c == '\'')
            used += (size_t)snprintf(literal + used, size - used, "\\x%02x", *c);
        else
            literal[used++] = (char)*c;
    }
    snprintf(literal + used, size - used, "'");
}

/* Give the candidate's home to the Python about to start (Linux; platform.h, GIVES_PYTHON_HOME):
 * Py_SetPythonHome, in the stable ABI of every Python 3 (deprecated since 3.11, kept in the ABI),
 * needs a string that lives as long as the process: never freed, as Python is never finalised. */
static int give_python_home(void *library, const char *home, char *problem, size_t size) {
    typedef void *(*DecodeLocale)(const char *, size_t *); /* wchar_t *Py_DecodeLocale(const char *, size_t *) */
    typedef void (*SetPythonHome)(const void *);          /* void Py_SetPythonHome(const wchar_t *) */
    DecodeLocale decode = (DecodeLocale)library_symbol(library, "Py_DecodeLocale");
    SetPythonHome set_home = (SetPythonHome)library_symbol(library, "Py_SetPythonHome");
    if (decode == NULL || set_home == NULL) {
        append(problem, size, "the loaded libpython has no %s", decode == NULL ? "Py_DecodeLocale" : "Py_SetPythonHome");
        return 0;
    }
    void *wide = decode(home, NULL);
    if (wide == NULL) {
        append(problem, size, "cannot decode the Python home %s", home);
        return 0;
    }
    set_home(wide);
    return 1;
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
        if (GIVES_PYTHON_HOME && !give_python_home(library, python->home, problem, size)) return 0;
        api->InitializeEx(0);
        size_t literal = 4 * strlen(python->executable) + 4, length = strlen(python->path) + literal + 128;
        char *executable = malloc(literal), *code = malloc(length);
        int ok = executable != NULL && code != NULL;
        if (ok) {
            bytes_literal(python->executable, executable, literal);
            snprintf(code, length, "import os, sys\nsys.path[:] = %s\nsys.executable = os.fsdecode(%s)\n",
                     python->path, executable);
            ok = run_in_process(api, code, "<greyfmu loader>", NULL, 0, NULL, NULL);
        }
        free(executable);
        free(code);
        api->EvalSaveThread(); /* Python stays initialised; pythonfmu takes the GIL per call */
        if (!ok) {
            append(problem, size, "cannot set sys.path of %s inside the host process", python->executable);
            return 0;
        }
    }
    return 1;
}


/* The buffers of ensure_python, on the heap (a host may call fmi2Instantiate on a small stack). */
typedef struct {
    char candidates[3][PATH_MAX];
    const char *origin[3];
    char file[PATH_MAX + 64];
    char tried[8192];
    char why[4096];
    Interpreter found;
} Search;

/* The candidates, in the loader's order (see the top comment); their number. */
static int find_candidates(const char *root, Search *search) {
    int count = 0;
    const char *chosen = getenv("GREYFMU_PYTHON");
    if (chosen != NULL && *chosen) {
        snprintf(search->candidates[count], PATH_MAX, "%s", chosen);
        search->origin[count++] = "GREYFMU_PYTHON";
        return count;
    }
    snprintf(search->file, sizeof search->file, "%s%cresources%cgreyfmu_build_python.txt", root, SEPARATOR,
             SEPARATOR);
    char *built_by = read_file(search->file);
    if (built_by != NULL) {
        built_by[strcspn(built_by, "\r\n")] = '\0';
        if (is_executable(built_by)) {
            snprintf(search->candidates[count], PATH_MAX, "%s", built_by);
            search->origin[count++] = "the interpreter that built the FMU";
        }
        free(built_by);
    }
    if (python_on_path(search->candidates[count], PATH_MAX)) search->origin[count++] = PYTHON_ON_PATH " on PATH";
    return count;
}

/* Find, load and initialise a Python in this process, unless it already runs one.  Never a second
 * libpython: one already loaded but not initialised is initialised, if it is the candidate's. */
static int ensure_python(const char *root, PythonApi *api, char *problem, size_t size) {
    void *host_python = loaded_python();
    if (host_python != NULL) {
        if (!resolve(host_python, api, problem, size)) return 0;
        if (api->IsInitialized()) return 1;
    }
    Search *search = calloc(1, sizeof *search);
    if (search == NULL) {
        append(problem, size, "out of memory looking for a Python");
        return 0;
    }
    int count = find_candidates(root, search), ok = 0, chosen = 0;
    if (count == 0)
        append(problem, size, "no Python found: GREYFMU_PYTHON is not set, the interpreter that built the FMU is not on "
                              "this machine and there is no " PYTHON_ON_PATH " on PATH");
    for (int i = 0; i < count && !chosen; i++) {
        const char *candidate = search->candidates[i];
        if (!is_executable(candidate)) {
            append(search->tried, sizeof search->tried, "%s%s (%s) is not an executable file",
                   *search->tried ? "; " : "", candidate, search->origin[i]);
            continue;
        }
        Interpreter *found = &search->found;
        search->why[0] = '\0';
        if (!query_candidate(candidate, root, found, search->why, sizeof search->why)) {
            append(search->tried, sizeof search->tried, "%s%s (%s): %s", *search->tried ? "; " : "", candidate,
                   search->origin[i], search->why);
            continue;
        }
        chosen = 1;
        ok = host_python == NULL || is_loaded_python(host_python, found->libpython);
        if (!ok)
            append(problem, size, "this process already has a libpython, not initialised, that is not %s's (%s): "
                   "set GREYFMU_PYTHON to the Python of the host's libpython", found->executable, found->libpython);
        ok = ok && start_python(found, api, problem, size);
        free(found->path);
    }
    if (count > 0 && !chosen) append(problem, size, "no usable Python: %s", search->tried);
    free(search);
    return ok;
}

/* A Python running in the process, started once per process under the lock every greyfmu loader
 * shares (platform.h find_process): its API in *api; 0 with the reason in `problem`. */
static int start_process_python(const char *root, PythonApi *api, char *problem, size_t size) {
    if (!find_process(problem, size)) return 0;
    int ready = python_ready();
    if (!ready) process_lock();
    int ok = ensure_python(root, api, problem, size);
    if (ok && !ready) set_python_ready();
    if (!ready) process_unlock();
    return ok;
}

/* Before each forwarded fmi2Instantiate, inside the process (`folder`: the instance's resources
 * folder; __file__: this FMU's resources/greyfmu_target.py).  The slave module is
 * `<package>.<model>`, all of the FMU's code under its private package (greyfmu.privatise).
 *  - The first instance of this code in the process (its package not imported yet) runs the
 *    target check (Python version, requirements: `problem`); a pass is not checked again, since
 *    the modules it imported stay (the loader's statics cannot remember it: fmpy unloads the
 *    library after each instance).
 *  - A later one points the package at `folder` (fmus/_inprocess.py): the folder it was imported
 *    from may have been deleted since (fmpy extracts each run into a new one).
 *  - Python's signal module is imported here, where the host's signal dispositions are put back
 *    afterwards: imported later, in a step, it would install Python's SIGINT handler for good.
 *  - `paths`: how often `folder` is on sys.path before pythonfmu inserts it. */
static const char PREPARE_INSTANCE[] =
    "import os, signal, sys\n"
    "with open(os.path.join(folder, 'slavemodule.txt'), encoding='utf-8') as listing:\n"
    "    module = listing.readline().strip()\n"
    "package = module.partition('.')[0]\n"
    "problem = ''\n"
    "if package not in sys.modules:\n"
    "    namespace = {'__name__': 'greyfmu_target', '__file__': __file__, '__builtins__': __builtins__}\n"
    "    with open(__file__, 'rb') as script:\n"
    "        exec(compile(script.read(), __file__, 'exec'), namespace)\n"
    "    problem = namespace['problem']\n"
    "elif package + '._inprocess' in sys.modules:\n"
    "    sys.modules[package + '._inprocess'].point_package_at(folder)\n"
    "paths = str(sys.path.count(folder))\n";

/* Before and after the forwarded fmi2Instantiate (PREPARE_INSTANCE, FINISH_INSTANCE); 0 with the
 * reason in `problem` if the instance cannot be made. */
static int prepare_instance(const char *folder, char *module, size_t module_size, char *paths, size_t paths_size,
                            char *problem, size_t size) {
    char *script = malloc(sizeof resources + 32), answer[2048];
    if (script == NULL) {
        append(problem, size, "out of memory preparing the instance");
        return 0;
    }
    snprintf(script, sizeof resources + 32, "%s%cgreyfmu_target.py", resources, SEPARATOR);
    PyVariable variables[] = {{"folder", (char *)folder, 0}, {"problem", answer, sizeof answer},
                              {"module", module, module_size}, {"paths", paths, paths_size}};
    int ran = run_in_process(&python_api, PREPARE_INSTANCE, script, variables, 4, NULL, NULL);
    if (!ran) append(problem, size, "checking the FMU's Python inside the host process raised a Python exception "
                                    "(printed on stderr)");
    else if (*answer) append(problem, size, "%s", answer);
    free(script);
    return ran && !*answer;
}

#endif
