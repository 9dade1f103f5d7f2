/* FMU states behind the guard (fmi2_loader.c, fmi3_loader.c; FMI 2.0 §2.1.8), the way Simulink's operating
 * points use them.
 *
 * A state pythonfmu 0.7.0 makes is the Python object the slave's _get_fmu_state returns, and its
 * fmi2FMUstate is that object's address.  Every state handed to the host (fmi2GetFMUstate,
 * fmi2DeSerializeFMUstate) is recorded here with the instance that made it, so that
 *  - a pointer that is no state of this FMU (freed already, another FMU's, never set) is refused
 *    with fmi2Error and a line, never dereferenced;
 *  - fmi2GetFMUstate with a previous state passed back (FMI 2.0 allows it; Simulink does it at
 *    every operating point) frees that state before making the new one: pythonfmu overwrote the
 *    pointer and leaked a whole state per call (+48.8 MB over 1000 steps of OSMMGPC);
 *  - fmi2FreeInstance frees the states its instance made and the host did not free.
 * Serialising goes through the slave's class here, not through pythonfmu: its
 * _fmu_state_to_bytes/_fmu_state_from_bytes (fmus/_state.py) raise a ValueError saying why for
 * bytes that are not a state of this model (another FMU's, truncated, random, empty), which is
 * answered with fmi2Error and that line; pythonfmu called them on the class, where an exception
 * released the instance's objects and returned fmi2Fatal, silently unless loggingOn.  The bytes
 * of the state last serialised are kept with the instance: a host asks for the size, then the
 * bytes, of one state.
 */
#ifndef GREYFMU_LOADER_STATES_H
#define GREYFMU_LOADER_STATES_H

typedef struct {
    void *state;
    GuardedInstance *owner;
} StateRecord;

static Lock states_lock = LOCK_INITIALIZER;
static StateRecord *states; /* every state handed out by this FMU's instances and not freed */
static size_t state_count, state_capacity;

static int remember_state(void *state, GuardedInstance *owner) {
    lock(&states_lock);
    int ok = state_count < state_capacity;
    if (!ok) {
        size_t capacity = state_capacity ? 2 * state_capacity : 16;
        StateRecord *grown = realloc(states, capacity * sizeof *grown);
        if ((ok = grown != NULL)) {
            states = grown;
            state_capacity = capacity;
        }
    }
    if (ok) states[state_count++] = (StateRecord){state, owner};
    unlock(&states_lock);
    return ok;
}

/* The index of `state`'s record (states_lock held); state_count if it has none. */
static size_t state_index(void *state) {
    size_t i = 0;
    while (i < state_count && states[i].state != state) i++;
    return i;
}

/* Forget `state`; whether it was one of this FMU's. */
static int forget_state(void *state) {
    lock(&states_lock);
    size_t i = state_index(state);
    int found = i < state_count;
    if (found) states[i] = states[--state_count];
    unlock(&states_lock);
    return found;
}

static int is_state(void *state) {
    lock(&states_lock);
    int found = state_index(state) < state_count;
    unlock(&states_lock);
    return found;
}

/* Release Python objects (NULLs skipped) under the GIL. */
static void release_objects(void *first, void *second) {
    if (first == NULL && second == NULL) return;
    int gil = python_api.GILStateEnsure();
    python_api.DecRef(first);
    python_api.DecRef(second);
    python_api.GILStateRelease(gil);
}

/* The last state `in` serialised is forgotten (its bytes released). */
static void forget_serialised(GuardedInstance *in) {
    release_objects(in->serialised_state, in->serialised_bytes);
    in->serialised_state = in->serialised_bytes = NULL;
}

/* Everything of the instance's in Python: its states the host did not free, its cache, its class. */
static void release_instance_objects(GuardedInstance *in) {
    for (;;) {
        void *state = NULL;
        lock(&states_lock);
        for (size_t i = 0; i < state_count && state == NULL; i++)
            if (states[i].owner == in) {
                state = states[i].state;
                states[i] = states[--state_count];
            }
        unlock(&states_lock);
        if (state == NULL) break;
        release_objects(state, NULL);
    }
    forget_serialised(in);
    release_objects(in->slave_class, NULL);
    in->slave_class = NULL;
}

/* The pending Python exception's text into `text` (cleared). */
static void python_error(char *text, size_t size) {
    void *type = NULL, *value = NULL, *traceback = NULL;
    python_api.ErrFetch(&type, &value, &traceback);
    void *shown = value != NULL ? python_api.ObjectStr(value) : NULL;
    void *bytes = shown != NULL ? python_api.UnicodeEncodeFSDefault(shown) : NULL;
    const char *message = bytes != NULL ? python_api.BytesAsString(bytes) : NULL;
    snprintf(text, size, "%s", message != NULL ? message : "a Python exception that cannot be shown");
    python_api.DecRef(bytes);
    python_api.DecRef(shown);
    python_api.DecRef(type);
    python_api.DecRef(value);
    python_api.DecRef(traceback);
}

/* slave_class.<method>(argument) under the GIL held by the caller: a new reference, or NULL with
 * the exception's text in `problem`. */
static void *call_slave_class(GuardedInstance *in, const char *method, void *argument, char *problem, size_t size) {
    void *function = in->slave_class != NULL ? python_api.GetAttrString(in->slave_class, method) : NULL;
    void *result = function != NULL ? python_api.CallFunctionObjArgs(function, argument, NULL) : NULL;
    if (result == NULL && in->slave_class == NULL)
        snprintf(problem, size, "the instance has no slave class to serialise states with");
    else if (result == NULL)
        python_error(problem, size);
    python_api.DecRef(function);
    return result;
}

/* The serialised bytes of `state` (kept with the instance until another state is serialised);
 * 0 with the reason in `problem`. */
static int serialised(GuardedInstance *in, void *state, char **bytes, size_t *size, char *problem, size_t psize) {
    int gil = python_api.GILStateEnsure();
    int ok = in->serialised_state == state;
    if (!ok) {
        void *made = call_slave_class(in, "_fmu_state_to_bytes", state, problem, psize);
        if ((ok = made != NULL)) {
            python_api.DecRef(in->serialised_state);
            python_api.DecRef(in->serialised_bytes);
            python_api.IncRef(state);
            in->serialised_state = state;
            in->serialised_bytes = made;
        }
    }
    intptr_t length = 0;
    if (ok && python_api.BytesAsStringAndSize(in->serialised_bytes, bytes, &length) != 0) {
        python_error(problem, psize);
        ok = 0;
    }
    *size = (size_t)length;
    python_api.GILStateRelease(gil);
    return ok;
}

/* The state serialised as `bytes`, a new reference; NULL with the reason in `problem`. */
static void *deserialised(GuardedInstance *in, const char *bytes, size_t size, char *problem, size_t psize) {
    int gil = python_api.GILStateEnsure();
    void *data = python_api.BytesFromStringAndSize(size > 0 ? bytes : "", (intptr_t)size);
    void *state = NULL;
    if (data == NULL)
        python_error(problem, psize);
    else
        state = call_slave_class(in, "_fmu_state_from_bytes", data, problem, psize);
    python_api.DecRef(data);
    python_api.GILStateRelease(gil);
    return state;
}

/* ---- the FMU state calls of both loaders, in the loader's names (STATE_TYPE "fmi2FMUstate",
 * STATE_ARGUMENT "FMUstate", GET_STATE, DESERIALIZE_STATE, SERIALIZED_STATE_SIZE) ---- */

/* fmi2GetFMUstate, fmi3GetFMUState: `forward` is pythonfmu's; a state passed back is freed before
 * the new one is made. */
static Status get_state(GuardedInstance *in, const char *function, void **state, Status (*forward)(void *, void **)) {
    if (state == NULL) REFUSE(in, function, STATE_ARGUMENT " (the " STATE_TYPE "* to fill) is NULL");
    if (*state != NULL) {
        if (!forget_state(*state))
            REFUSE(in, function, "*" STATE_ARGUMENT " = %p is no state of this FMU: pass NULL for a new state, or a "
                   "state " GET_STATE " or " DESERIALIZE_STATE " returned and that was not freed", *state);
        release_objects(*state, NULL);
        *state = NULL;
    }
    save_signals(&in->signals);
    Status status = forward(in->real, state);
    restore_signals(&in->signals);
    if (status <= STATUS(Warning) && *state != NULL && !remember_state(*state, in)) {
        release_objects(*state, NULL);
        *state = NULL;
        REFUSE(in, function, "out of memory recording the state");
    }
    return settle(in, function, status, 0);
}

/* fmi2SetFMUstate, fmi3SetFMUState: a state restored leaves the error state for the state the
 * instance had before it; the next step says the time. */
static Status set_state(GuardedInstance *in, const char *function, void *state, Status (*forward)(void *, void *)) {
    if (state == NULL) REFUSE(in, function, STATE_ARGUMENT " is NULL");
    if (!is_state(state)) REFUSE(in, function, STATE_ARGUMENT " = %p is no state of this FMU (freed?)", state);
    save_signals(&in->signals);
    Status status = settle(in, function, forward(in->real, state), 0);
    restore_signals(&in->signals);
    if (status <= STATUS(Warning) && in->phase == PHASE_ERROR) in->phase = in->phase_before_error;
    if (status <= STATUS(Warning)) in->time_known = 0;
    return status;
}

static Status free_state(GuardedInstance *in, const char *function, void **state) {
    if (state == NULL) REFUSE(in, function, STATE_ARGUMENT " (the " STATE_TYPE "* to free) is NULL");
    if (*state == NULL) return STATUS(OK); /* nothing to free */
    if (!forget_state(*state)) REFUSE(in, function, "*" STATE_ARGUMENT " = %p is no state of this FMU (freed already?)",
                                      *state);
    release_objects(*state, NULL);
    *state = NULL;
    return STATUS(OK);
}

static Status serialized_state_size(GuardedInstance *in, const char *function, void *state, size_t *size) {
    if (state == NULL || size == NULL) REFUSE(in, function, "%s is NULL", state == NULL ? STATE_ARGUMENT : "size");
    if (!is_state(state)) REFUSE(in, function, STATE_ARGUMENT " = %p is no state of this FMU", state);
    char *bytes, problem[2048];
    if (!serialised(in, state, &bytes, size, problem, sizeof problem)) REFUSE(in, function, "%s", problem);
    return STATUS(OK);
}

static Status serialize_state(GuardedInstance *in, const char *function, void *state, char bytes[], size_t size) {
    if (state == NULL) REFUSE(in, function, STATE_ARGUMENT " is NULL");
    if (bytes == NULL && size > 0) REFUSE(in, function, "serializedState is NULL with size = %zu", size);
    if (!is_state(state)) REFUSE(in, function, STATE_ARGUMENT " = %p is no state of this FMU", state);
    char *serialised_bytes, problem[2048];
    size_t needed;
    if (!serialised(in, state, &serialised_bytes, &needed, problem, sizeof problem)) REFUSE(in, function, "%s", problem);
    if (size != needed)
        REFUSE(in, function, "size = %zu, but the state's serialised size is %zu (" SERIALIZED_STATE_SIZE ")", size,
               needed);
    memcpy(bytes, serialised_bytes, needed);
    return STATUS(OK);
}

static Status deserialize_state(GuardedInstance *in, const char *function, const char bytes[], size_t size,
                                void **state) {
    if (bytes == NULL && size > 0) REFUSE(in, function, "serializedState is NULL with size = %zu", size);
    if (state == NULL) REFUSE(in, function, STATE_ARGUMENT " (the " STATE_TYPE "* to fill) is NULL");
    if (*state != NULL && forget_state(*state)) release_objects(*state, NULL); /* a state passed back */
    *state = NULL;
    char problem[2048];
    save_signals(&in->signals);
    void *made = deserialised(in, bytes, size, problem, sizeof problem);
    restore_signals(&in->signals);
    if (made == NULL) REFUSE(in, function, "%s", problem);
    if (!remember_state(made, in)) {
        release_objects(made, NULL);
        REFUSE(in, function, "out of memory recording the state");
    }
    *state = made;
    return STATUS(OK);
}

#endif
