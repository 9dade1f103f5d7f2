/* The guard of the greyfmu loaders (fmi2_loader.c, fmi3_loader.c): a host that misuses the FMU
 * gets fmi2Error (fmi3Error) and one log line, never a crash.  Said here for FMI 2.0; the FMI 3.0
 * loader's top comment says what differs (its state machine, calls and types).
 *
 * Before including it a loader defines its FMI version's names: `Status` and STATUS(OK) ...
 * STATUS(Fatal) (the two versions' status values are the same), FMI ("fmi2"), INSTANCE_TYPE, `HostCallbacks`,
 * PHASE_NAMES (the state names in Phase's order), TYPE_NAME_R/I/L (the types of the guard file's
 * letters), and after it `host_log`.
 *
 * fmi2Instantiate returns a `GuardedInstance` as the fmi2Component: it holds pythonfmu's
 * component, the instance's state in the FMI 2.0 Co-Simulation state machine (FMI 2.0 §4.2.4),
 * a copy of the host's callbacks and the FMU's variables (resources/greyfmu_guard.txt, written by
 * greyfmu.dropin.guard_text: the GUID, the longest step accepted, and one line per variable with
 * its value reference, type, causality, variability and initial).  Every exported function checks
 * its call against them before forwarding to pythonfmu: the state, NULL pointers (instance,
 * arrays with n > 0, callbacks, logger), value references (unknown, or of another type), which
 * variables may be set in the state (FMI 2.0 §4.2.4 Table, footnotes 1, 3 and 6), step sizes
 * (finite, > 0, at most max_step, starting where the last step ended and ending by stopTime, as
 * the Reference FMUs check) and, at instantiation, the GUID, the interface type
 * (Co-Simulation only) and the resource location (every RFC 8089 form, normalised to the plain
 * folder path pythonfmu uses).  A refused call is not forwarded; it returns fmi2Error after one
 * line through the host's logger naming the function, the argument and the state, and the
 * instance enters the error state, as after any fmi2Error (only get, reset, free, FMU states
 * and debug logging are then allowed; fmi2Reset or fmi2SetFMUstate leave it).
 *
 * Every message reaches the host's logger as data: logger(env, name, status, category, "%s",
 * text).  pythonfmu passes its messages as the format (`%s%n` in a message crashed hosts), so
 * pythonfmu is given the guard's own callbacks, whose logger forwards that format verbatim as the
 * "%s" argument.
 *
 * Never silent (FMI 2.0 §2.1.5: the logger explains a NULL from fmi2Instantiate): pythonfmu
 * logs nothing at all unless loggingOn (its PyLogger drops every message, errors included), so
 * it is always instantiated with logging on and the guard filters instead: a message of status
 * fmi2Warning or worse always reaches the host, an fmi2OK one only while the host's loggingOn
 * (fmi2SetDebugLogging, which the guard answers itself) and its categories ask for it.  A call
 * that returns fmi2Discard, fmi2Error or fmi2Fatal (or NULL) without a line of that status from
 * pythonfmu or the slave gets one from the guard.
 *
 * fmi2Fatal only where FMI 2.0 §2.1.3 means it (all instances corrupted): pythonfmu answers
 * every Python exception with fmi2Fatal.  The slave says an exception it survives in one line
 * of category PYTHON_EXCEPTION (fmus/_slave.py) and gives back what pythonfmu releases for it;
 * the guard then answers fmi2Error and drops pythonfmu's "Fatal py exception" line, and the
 * instance is in the error state (fmi2Reset, fmi2SetFMUstate, fmi2FreeInstance).  Only an
 * exception without that line (pythonfmu's instance then lost) stays fmi2Fatal.
 */
#ifndef GREYFMU_LOADER_GUARD_H
#define GREYFMU_LOADER_GUARD_H

#include <ctype.h>
#include <math.h>

#define GUARD_MAGIC 0x67726579u /* "grey": a live GuardedInstance */
#define GUARD_FILE "greyfmu_guard.txt"
#define PYTHON_EXCEPTION "logPythonException" /* fmus/_slave.py PYTHON_EXCEPTION */

typedef enum {
    PHASE_INSTANTIATED = 1,
    PHASE_INITIALIZATION = 2,
    PHASE_STEP_COMPLETE = 4,
    PHASE_STEP_FAILED = 8,
    PHASE_STEP_CANCELED = 16,
    PHASE_TERMINATED = 32,
    PHASE_ERROR = 64,
    PHASE_FATAL = 128
} Phase;

/* The states each function is allowed in (FMI 2.0 §4.2.4; stepInProgress never happens here:
 * fmi2DoStep is synchronous). */
#define PHASES_ANY_BUT_FATAL                                                                                       \
    (PHASE_INSTANTIATED | PHASE_INITIALIZATION | PHASE_STEP_COMPLETE | PHASE_STEP_FAILED | PHASE_STEP_CANCELED |   \
     PHASE_TERMINATED | PHASE_ERROR)
#define PHASES_GET                                                                                                 \
    (PHASE_INITIALIZATION | PHASE_STEP_COMPLETE | PHASE_STEP_FAILED | PHASE_STEP_CANCELED | PHASE_TERMINATED |     \
     PHASE_ERROR)
#define PHASES_SET (PHASE_INSTANTIATED | PHASE_INITIALIZATION | PHASE_STEP_COMPLETE)
#define PHASES_STATUS (PHASE_STEP_COMPLETE | PHASE_STEP_FAILED | PHASE_TERMINATED)
#define PHASES_OUTPUT_DERIVATIVES (PHASE_STEP_COMPLETE | PHASE_STEP_FAILED | PHASE_STEP_CANCELED | PHASE_TERMINATED | PHASE_ERROR)

/* The state's name in the loader's FMI version (the loader's PHASE_NAMES, in Phase's order). */
static const char *phase_name(Phase phase) {
    static const char *const names[] = {PHASE_NAMES};
    int index = 0;
    while (index < 7 && (1 << index) != (int)phase) index++;
    return names[index];
}

/* The names of the states in `phases`, comma-separated. */
static void phase_names(int phases, char *text, size_t size) {
    text[0] = '\0';
    for (int phase = PHASE_INSTANTIATED; phase <= PHASE_FATAL; phase <<= 1)
        if (phases & phase) append(text, size, "%s%s", *text ? ", " : "", phase_name((Phase)phase));
}

typedef struct {
    unsigned int vr;
    char type;               /* R, I (Integer and Enumeration), B, S */
    const char *causality;   /* parameter, calculatedParameter, input, output, local, independent */
    const char *variability; /* constant, fixed, tunable, discrete, continuous */
    const char *initial;     /* exact, approx, calculated, none */
    const char *name;
} GuardVariable;

typedef struct {
    char *text; /* the guard file, its lines cut into the strings below */
    const char *guid;
    double max_step; /* 0: no bound but finiteness */
    GuardVariable *variables;
    size_t count;
} GuardModel;

typedef struct {
    unsigned magic;
    void *real; /* pythonfmu's component */
    Phase phase;
    Phase phase_before_error;
    char *name;
    HostCallbacks host;              /* the host's callbacks, copied (the loader's type) */
    HostCallbacks forwarded;         /* given to pythonfmu (FMI 2.0): guard_logger, componentEnvironment = this */
    GuardModel model;
    int time_known;   /* next_time is where the next step starts (unknown after a reset or a restored state) */
    double next_time;
    int stop_defined; /* fmi2SetupExperiment's stopTime: no step may end after it */
    double stop_time;
    int logging_on;   /* the host's loggingOn (fmi2Instantiate, fmi2SetDebugLogging): OK lines pass only then */
    char **categories;/* the categories fmi2SetDebugLogging named (count 0: all) */
    size_t category_count;
    int explained;    /* a line of status Discard or worse reached the host during the current call */
    int recoverable;  /* the slave said an exception it survived during the current call (PYTHON_EXCEPTION) */
    void *slave_class;         /* the slave's class, a strong reference (states.h serialises with it) */
    void *serialised_state;    /* the state last serialised and its bytes, strong references (states.h) */
    void *serialised_bytes;
    HostSignals signals;       /* the host's signal dispositions during a call into Python (platform.h) */
} GuardedInstance;

/* Two communication times that are the same time up to rounding. */
static int same_time(double a, double b) {
    double scale = fabs(a) > fabs(b) ? fabs(a) : fabs(b);
    return fabs(a - b) <= 1e-9 * (scale > 1 ? scale : 1);
}

/* The type of a guard file's letter, in the loader's FMI version (TYPE_NAME_R, ...). */
static const char *type_name(char type) {
    return type == 'R' ? TYPE_NAME_R : type == 'I' ? TYPE_NAME_I : type == 'L' ? TYPE_NAME_L : type == 'B' ? "Boolean"
                                                                                                        : "String";
}

/* ---- the model: resources/greyfmu_guard.txt ---- */

static int compare_variables(const void *a, const void *b) {
    const GuardVariable *x = a, *y = b;
    if (x->type != y->type) return x->type < y->type ? -1 : 1;
    return x->vr < y->vr ? -1 : x->vr > y->vr;
}

/* The next space-separated word of *cursor, NUL-terminated in place. */
static char *next_word(char **cursor) {
    char *word = *cursor;
    while (*word == ' ') word++;
    char *end = word + strcspn(word, " ");
    if (*end) *end++ = '\0';
    *cursor = end;
    return word;
}

static void free_model(GuardModel *model) {
    free(model->text);
    free(model->variables);
    memset(model, 0, sizeof *model);
}

/* Read folder/greyfmu_guard.txt into model; 0 with problem set if it is missing or malformed. */
static int read_model(const char *folder, GuardModel *model, char *problem, size_t size) {
    char path[PATH_MAX + 64];
    snprintf(path, sizeof path, "%s%c%s", folder, SEPARATOR, GUARD_FILE);
    memset(model, 0, sizeof *model);
    if ((model->text = read_file(path)) == NULL) {
        append(problem, size, "cannot read %s (the FMU is incomplete)", path);
        return 0;
    }
    size_t lines = 1;
    for (const char *c = model->text; *c; c++) lines += *c == '\n';
    model->variables = calloc(lines, sizeof *model->variables);
    char *line = model->text;
    while (model->variables != NULL && *line) {
        char *end = line + strcspn(line, "\r\n");
        char *following = end + strspn(end, "\r\n");
        *end = '\0';
        char *cursor = line;
        const char *key = next_word(&cursor);
        if (strcmp(key, "guid") == 0) {
            model->guid = next_word(&cursor);
        } else if (strcmp(key, "max_step") == 0) {
            model->max_step = strtod(next_word(&cursor), NULL);
        } else if (strcmp(key, "variable") == 0) {
            GuardVariable *v = &model->variables[model->count++];
            v->vr = (unsigned int)strtoul(next_word(&cursor), NULL, 10);
            v->type = *next_word(&cursor);
            v->causality = next_word(&cursor);
            v->variability = next_word(&cursor);
            v->initial = next_word(&cursor);
            v->name = cursor;
        }
        line = following;
    }
    if (model->variables == NULL || model->guid == NULL) {
        append(problem, size, model->variables == NULL ? "out of memory reading %s" : "%s has no GUID line (the FMU is "
               "damaged)", path);
        free_model(model);
        return 0;
    }
    qsort(model->variables, model->count, sizeof *model->variables, compare_variables);
    return 1;
}

static const GuardVariable *find_variable(const GuardModel *model, char type, unsigned int vr) {
    GuardVariable key = {.vr = vr, .type = type};
    return bsearch(&key, model->variables, model->count, sizeof *model->variables, compare_variables);
}

/* The variable of any type with this value reference (to say what a wrong-typed one is). */
static const GuardVariable *any_variable(const GuardModel *model, unsigned int vr) {
    for (size_t i = 0; i < model->count; i++)
        if (model->variables[i].vr == vr) return &model->variables[i];
    return NULL;
}

/* ---- logging: text is data ---- */

/* One line to the host's logger, as data (defined by the loader: FMI 2.0's logger takes a format,
 * FMI 3.0's a message). */
static void host_log(const GuardedInstance *in, Status status, const char *category, const char *text);

static const char *status_category(Status status) {
    return status == STATUS(OK)        ? "logAll"
           : status == STATUS(Warning) ? "logStatusWarning"
           : status == STATUS(Discard) ? "logStatusDiscard"
           : status == STATUS(Fatal)   ? "logStatusFatal"
                                   : "logStatusError";
}

static const char *status_name(Status status) {
    static const char *names[] = {FMI "OK", FMI "Warning", FMI "Discard", FMI "Error", FMI "Fatal"};
    return status >= STATUS(OK) && status <= STATUS(Fatal) ? names[status] : "an unknown status";
}

/* Whether an OK line of `category` is one the host asked for (loggingOn, its categories). */
static int wanted(const GuardedInstance *in, const char *category) {
    if (!in->logging_on) return 0;
    for (size_t i = 0; i < in->category_count; i++)
        if (strcmp(in->categories[i], category) == 0) return 1;
    return in->category_count == 0;
}

/* pythonfmu's logger: it passes each message as the format, with no arguments; the host
 * receives it as the "%s" argument, never as a format, filtered as the top comment says. */
static void guard_message(GuardedInstance *in, Status status, const char *category, const char *message) {
    const char *text = message != NULL ? message : "";
    if (category != NULL && strcmp(category, PYTHON_EXCEPTION) == 0) {
        in->recoverable = 1;
        status = STATUS(Error); /* the explanation of the Error the call returns */
    } else if (status == STATUS(Fatal) && (in->recoverable || in->real == NULL)) {
        if (in->recoverable) return; /* pythonfmu's "Fatal py exception" for the exception the slave just said */
        status = STATUS(Error);          /* why the instantiation returns NULL: nothing else is lost */
    }
    if (category == NULL || *category == '\0') category = status_category(status);
    if (status >= STATUS(Discard))
        in->explained = 1;
    else if (status == STATUS(OK) && !wanted(in, category))
        return;
    char *one_line = strchr(text, '\n') != NULL ? strdup(text) : NULL; /* pythonfmu's "...: [ctor] findClass\n<repr>" */
    for (char *c = one_line; c != NULL && *c; c++)
        if (*c == '\n' || *c == '\r') *c = ' ';
    host_log(in, status, category, one_line != NULL ? one_line : text);
    free(one_line);
}

/* One line through the host's logger: "<function>: <text> (instance '<name>', state <state>)". */
static void guard_say(const GuardedInstance *in, Status status, const char *function, const char *format, ...) {
    char text[2048];
    va_list args;
    va_start(args, format);
    vsnprintf(text, sizeof text, format, args);
    va_end(args);
    char line[2400];
    snprintf(line, sizeof line, "%s: %s (instance '%s', state %s)", function, text, in->name, phase_name(in->phase));
    host_log(in, status, status_category(status), line);
}

static void enter_error(GuardedInstance *in) {
    if (in->phase == PHASE_FATAL || in->phase == PHASE_ERROR) return;
    in->phase_before_error = in->phase;
    in->phase = PHASE_ERROR;
}

/* Refuse a call: one line, the error state, Error. */
#define REFUSE(in, function, ...)                                                                                  \
    do {                                                                                                           \
        guard_say(in, STATUS(Error), function, __VA_ARGS__);                                                           \
        enter_error(in);                                                                                           \
        return STATUS(Error);                                                                                          \
    } while (0)

/* ---- the checks ---- */

/* The GuardedInstance behind c; NULL (one line on stderr: there is no logger to use) if c is
 * NULL or not a live instance of this FMU. */
static GuardedInstance *guarded(void *c, const char *function) {
    GuardedInstance *in = c;
    if (in == NULL) {
        fprintf(stderr, "greyfmu: %s: the instance (" INSTANCE_TYPE ") is NULL\n", function);
        return NULL;
    }
    if (in->magic != GUARD_MAGIC) {
        fprintf(stderr, "greyfmu: %s: %p is not a live instance of this FMU (freed, or another FMU's)\n", function, c);
        return NULL;
    }
    return in;
}

/* 1 if `function` is allowed in the instance's state; otherwise the refusal is logged. */
static int allowed_in(GuardedInstance *in, const char *function, int phases) {
    if (in->phase & phases) return 1;
    char names[256];
    phase_names(phases, names, sizeof names);
    if (in->phase == PHASE_FATAL)
        guard_say(in, STATUS(Error), function, "not allowed: the instance returned " FMI "Fatal, only " FMI "FreeInstance is");
    else if (phases == 0)
        guard_say(in, STATUS(Error), function, "not allowed: no step is ever in progress (" FMI "DoStep is synchronous)");
    else
        guard_say(in, STATUS(Error), function, "not allowed in this state (allowed in: %s)", names);
    enter_error(in);
    return 0;
}

/* Whether variable v may be set in `phase` (FMI 2.0 §4.2.4 Table, footnotes 1, 3 and 6); the
 * reason it may not in `why`. */
static int settable(const GuardVariable *v, Phase phase, char *why, size_t size) {
    int input = strcmp(v->causality, "input") == 0;
    if (strcmp(v->variability, "constant") == 0) {
        snprintf(why, size, "is a constant: it cannot be set");
        return 0;
    }
    if (phase == PHASE_INSTANTIATED && !(input || !strcmp(v->initial, "exact") || !strcmp(v->initial, "approx"))) {
        snprintf(why, size, "is a %s %s with initial=%s: it cannot be set before initialisation", v->variability,
                 v->causality, v->initial);
        return 0;
    }
    if (phase == PHASE_INITIALIZATION && !(input || !strcmp(v->initial, "exact"))) {
        snprintf(why, size, "is a %s %s with initial=%s: it cannot be set in initialisation mode", v->variability,
                 v->causality, v->initial);
        return 0;
    }
    if (phase == PHASE_STEP_COMPLETE &&
        !(input || (!strcmp(v->causality, "parameter") && !strcmp(v->variability, "tunable")))) {
        snprintf(why, size, "is a %s %s: after initialisation only inputs and tunable parameters can be set",
                 v->variability, v->causality);
        return 0;
    }
    return 1;
}

/* Check a get/set call's arrays and value references (type: R, I, B, S; setting: a set call). */
static int references_ok(GuardedInstance *in, const char *function, const unsigned int vr[], size_t n,
                         const void *values, char type, int setting) {
    if (n > 0 && vr == NULL) {
        guard_say(in, STATUS(Error), function, "the value reference array vr is NULL with nvr = %zu", n);
        enter_error(in);
        return 0;
    }
    if (n > 0 && values == NULL) {
        guard_say(in, STATUS(Error), function, "the value array is NULL with nvr = %zu", n);
        enter_error(in);
        return 0;
    }
    for (size_t i = 0; i < n; i++) {
        const GuardVariable *v = find_variable(&in->model, type, vr[i]);
        char why[512] = "";
        if (v == NULL) {
            const GuardVariable *other = any_variable(&in->model, vr[i]);
            if (other != NULL)
                snprintf(why, sizeof why, "vr[%zu] = %u is %s, a %s variable, not of type %s", i, vr[i], other->name,
                         type_name(other->type), type_name(type));
            else
                snprintf(why, sizeof why, "vr[%zu] = %u is not a value reference of this FMU", i, vr[i]);
        } else if (setting && type == 'S' && ((const char *const *)values)[i] == NULL) {
            snprintf(why, sizeof why, "value[%zu] (for %s) is NULL", i, v->name);
        } else if (setting) {
            char reason[400];
            if (!settable(v, in->phase, reason, sizeof reason))
                snprintf(why, sizeof why, "vr[%zu] = %u: %s %s", i, vr[i], v->name, reason);
        }
        if (*why) {
            guard_say(in, STATUS(Error), function, "%s", why);
            enter_error(in);
            return 0;
        }
    }
    return 1;
}

/* What a forwarded call returns to the host (see the top comment): Error for an exception
 * the slave survived, and a line of its own for a failure nothing explained. */
static Status answered(GuardedInstance *in, const char *function, Status status) {
    if (status == STATUS(Fatal) && in->recoverable) status = STATUS(Error);
    if (status >= STATUS(Discard) && status <= STATUS(Fatal) && !in->explained)
        guard_say(in, status, function, "pythonfmu returned %s without saying why", status_name(status));
    return status;
}

/* The state after a forwarded call returned `status` (`next` when it succeeded; 0: unchanged);
 * the status `answered` gives the host. */
static Status settle(GuardedInstance *in, const char *function, Status status, int next) {
    status = answered(in, function, status);
    if (status == STATUS(Error)) enter_error(in);
    else if (status == STATUS(Fatal)) in->phase = PHASE_FATAL;
    else if (status <= STATUS(Warning) && next) in->phase = (Phase)next;
    return status;
}

/* ---- what the guard answers itself ---- */

static void forget_categories(GuardedInstance *in) {
    for (size_t i = 0; i < in->category_count; i++) free(in->categories[i]);
    free(in->categories);
    in->categories = NULL;
    in->category_count = 0;
}

static void free_guarded(GuardedInstance *in) {
    in->magic = 0;
    free_model(&in->model);
    forget_categories(in);
    free(in->name);
    free(in);
}

/* fmi2SetDebugLogging, fmi3SetDebugLogging: the host's loggingOn and categories, copied. */
static Status debug_logging(GuardedInstance *in, const char *function, int on, size_t n, const char *const categories[]) {
    if (n > 0 && categories == NULL) REFUSE(in, function, "categories is NULL with nCategories = %zu", n);
    for (size_t i = 0; i < n; i++)
        if (categories[i] == NULL) REFUSE(in, function, "categories[%zu] is NULL", i);
    char **copied = n > 0 ? calloc(n, sizeof *copied) : NULL;
    for (size_t i = 0; copied != NULL && i < n; i++)
        if ((copied[i] = strdup(categories[i])) == NULL) {
            while (i > 0) free(copied[--i]);
            free(copied);
            copied = NULL;
        }
    if (n > 0 && copied == NULL) REFUSE(in, function, "out of memory copying %zu categories", n);
    forget_categories(in);
    in->categories = copied;
    in->category_count = n;
    in->logging_on = on;
    return STATUS(OK);
}

/* ---- the resource location ---- */

static int hex_value(char c) {
    if (c >= '0' && c <= '9') return c - '0';
    c = (char)tolower((unsigned char)c);
    return c >= 'a' && c <= 'f' ? c - 'a' + 10 : -1;
}

/* The folder of a file URI's path part (percent-decoded); 0 with problem set if malformed. */
static int decode_path(const char *encoded, char *folder, size_t size, char *problem, size_t psize) {
    size_t length = 0;
    for (const char *c = encoded; *c; c++) {
        char byte = *c;
        if (byte == '%') {
            int high = hex_value(c[1]), low = high < 0 ? -1 : hex_value(c[2]);
            if (low < 0 || (high == 0 && low == 0)) {
                append(problem, psize, "has '%.3s', which is not a valid percent-encoded byte", c);
                return 0;
            }
            byte = (char)(high * 16 + low);
            c += 2;
        }
        if (length + 1 >= size) {
            append(problem, psize, "is too long");
            return 0;
        }
        folder[length++] = byte;
    }
    folder[length] = '\0';
#ifdef _WIN32
    /* /C:/path -> C:/path */
    if (folder[0] == '/' && isalpha((unsigned char)folder[1]) && folder[2] == ':') memmove(folder, folder + 1, length);
#endif
    return 1;
}

static int has_drive(const char *path) { return isalpha((unsigned char)path[0]) && path[1] == ':'; }

/* Whether text is well-formed UTF-8 (RFC 3629: no overlong forms, surrogates or code points past
 * U+10FFFF).  pythonfmu 0.7.0 decodes the resources folder it is given as UTF-8 and crashes the
 * host on one that is not (PySlaveInstance::handle_py_exception), so such a folder is refused. */
static int is_utf8(const char *text) {
    const unsigned char *c = (const unsigned char *)text;
    while (*c) {
        int follow = *c < 0x80 ? 0 : (*c >= 0xC2 && *c <= 0xDF) ? 1 : (*c >= 0xE0 && *c <= 0xEF) ? 2
                   : (*c >= 0xF0 && *c <= 0xF4) ? 3 : -1;
        if (follow < 0) return 0;
        unsigned int low = 0x80, high = 0xBF; /* the second byte's range */
        if (*c == 0xE0) low = 0xA0;
        if (*c == 0xED) high = 0x9F;
        if (*c == 0xF0) low = 0x90;
        if (*c == 0xF4) high = 0x8F;
        for (int i = 1; i <= follow; i++)
            if (c[i] < (i == 1 ? low : 0x80) || c[i] > (i == 1 ? high : 0xBF)) return 0;
        c += 1 + follow;
    }
    return 1;
}

/* The resources folder a fmuResourceLocation names, as the plain path pythonfmu uses:
 * file:/path, file:///path, file://localhost/path (percent-encoded), or a plain path; NULL or
 * empty: the FMU's own resources folder (*fallback set).  0 with problem set otherwise. */
static int resource_folder(const char *location, const char *root, char *folder, size_t size, int *fallback,
                           char *problem, size_t psize) {
    *fallback = location == NULL || *location == '\0';
    if (*fallback) {
        snprintf(folder, size, "%s%cresources", root, SEPARATOR);
    } else if (strncmp(location, "file:", 5) == 0 || strncmp(location, "FILE:", 5) == 0) {
        const char *path = location + 5;
        if (strncmp(path, "//", 2) == 0) {
            const char *host = path + 2;
            size_t host_length = strcspn(host, "/");
            if (host_length > 0 && !(host_length == 9 && strncmp(host, "localhost", 9) == 0)) {
                append(problem, psize, "names the host '%.*s': only local files (file:///path) are supported",
                       (int)host_length, host);
                return 0;
            }
            path = host + host_length;
        }
        if (path[0] != '/' && !has_drive(path)) {
            append(problem, psize, "is not an absolute file URI (file:///path)");
            return 0;
        }
        if (!decode_path(path, folder, size, problem, psize)) return 0;
    } else {
        size_t scheme = strspn(location, "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789+.-");
        if (scheme > 1 && location[scheme] == ':') {
            append(problem, psize, "is a '%.*s:' URI: only file URIs and paths are supported", (int)scheme, location);
            return 0;
        }
        snprintf(folder, size, "%s", location);
    }
    size_t length = strlen(folder);
    while (length > 1 && (folder[length - 1] == '/' || folder[length - 1] == '\\')) folder[--length] = '\0';
    if (!is_directory(folder)) {
        append(problem, psize, "is the folder %s, which does not exist", folder);
        return 0;
    }
    if (!is_utf8(folder)) {
        append(problem, psize, "is the folder %s, whose path is not UTF-8 text, which pythonfmu 0.7.0 needs: move the "
               "FMU's files to a folder whose path is UTF-8", folder);
        return 0;
    }
    char module[PATH_MAX + 64];
    snprintf(module, sizeof module, "%s%cslavemodule.txt", folder, SEPARATOR);
    FILE *file = fopen(module, "rb");
    if (file == NULL) {
        append(problem, psize, "is the folder %s, which has no slavemodule.txt: not this FMU's resources", folder);
        return 0;
    }
    fclose(file);
    return 1;
}

#endif
