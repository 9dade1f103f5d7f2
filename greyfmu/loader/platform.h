/* Platform layer of the greyfmu loaders (fmi2_loader.c, fmi3_loader.c): Linux (POSIX) and Windows.
 *
 * Libraries (open, look up, a Python already in the process), the loader's own path, files,
 * a lock, the process-wide lock and ready flag every loader shares, the host's signal
 * dispositions, and running the check script in a child process with a time limit.
 */
#ifndef GREYFMU_LOADER_PLATFORM_H
#define GREYFMU_LOADER_PLATFORM_H

#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#ifndef QUERY_SECONDS /* tests build a loader with a shorter limit */
#define QUERY_SECONDS 60
#endif
#define OUTPUT_LIMIT (1 << 20) /* what is kept of a candidate's output; the rest is read and dropped */

static void append(char *buffer, size_t size, const char *format, ...) {
    size_t used = strlen(buffer);
    if (used + 1 >= size) return;
    va_list args;
    va_start(args, format);
    vsnprintf(buffer + used, size - used, format, args);
    va_end(args);
}

/* The end of run_query: the child's output in *output, or the time-out as the problem. */
static int query_answer(char *text, int timed_out, const char *python, char **output, char *problem, size_t size) {
    if (text == NULL) {
        append(problem, size, "out of memory reading the answer of %s", python);
        return 0;
    }
    if (timed_out) {
        append(problem, size, "%s did not answer within %d s", python, QUERY_SECONDS);
        free(text);
        return 0;
    }
    *output = text;
    return 1;
}

#ifdef _WIN32
/* ------------------------------------------------------------------ Windows */
#include <windows.h>
#include <psapi.h>
#include <signal.h>

#define EXPORT __declspec(dllexport)
#undef PATH_MAX
#define PATH_MAX 1024
#define SEPARATOR '\\'
#define PATH_LIST_SEPARATOR ";"
#define PLATFORM_FOLDER "win64"
#define PLATFORM_FOLDER3 "x86_64-windows" /* FMI 3.0 */
#define LIBRARY_SUFFIX ".dll"
#define PYTHON_ON_PATH "python.exe"

typedef SRWLOCK Lock;
#define LOCK_INITIALIZER SRWLOCK_INIT
static void lock(Lock *l) { AcquireSRWLockExclusive(l); }
static void unlock(Lock *l) { ReleaseSRWLockExclusive(l); }

static void *library_open(const char *path, int global, char *problem, size_t size) {
    (void)global; /* Windows resolves imports by module name: a loaded python3XX.dll serves every later DLL */
    HMODULE library = LoadLibraryExA(path, NULL, LOAD_WITH_ALTERED_SEARCH_PATH);
    if (library == NULL) append(problem, size, "cannot load %s (Windows error %lu)", path, GetLastError());
    return (void *)library;
}

static void *library_symbol(void *library, const char *name) {
    return (void *)GetProcAddress((HMODULE)library, name);
}

/* pythonXY.dll (not the stable-ABI python3.dll) if one is loaded in this process. */
static void *loaded_python(void) {
    HMODULE modules[1024];
    DWORD needed = 0;
    if (!EnumProcessModules(GetCurrentProcess(), modules, sizeof modules, &needed)) return NULL;
    for (DWORD i = 0; i < needed / sizeof(HMODULE) && i < 1024; i++) {
        char name[MAX_PATH];
        if (!GetModuleBaseNameA(GetCurrentProcess(), modules[i], name, sizeof name)) continue;
        if (_strnicmp(name, "python3", 7) == 0 && _stricmp(name, "python3.dll") != 0 && strlen(name) > 11 &&
            _stricmp(name + strlen(name) - 4, ".dll") == 0)
            return (void *)modules[i];
    }
    return NULL;
}

/* Whether the file `path` is the pythonXY.dll `python` (from loaded_python) already in this process. */
static int is_loaded_python(void *python, const char *path) { return GetModuleHandleA(path) == (HMODULE)python; }

static int library_path(char *path, size_t size) {
    HMODULE self;
    if (!GetModuleHandleExA(GET_MODULE_HANDLE_EX_FLAG_FROM_ADDRESS | GET_MODULE_HANDLE_EX_FLAG_UNCHANGED_REFCOUNT,
                            (LPCSTR)&library_path, &self))
        return 0;
    DWORD length = GetModuleFileNameA(self, path, (DWORD)size);
    for (DWORD i = 0; i < length; i++)
        if (path[i] == '/') path[i] = '\\';
    return length > 0 && length < size;
}

static int is_directory(const char *path) {
    DWORD attributes = GetFileAttributesA(path);
    return attributes != INVALID_FILE_ATTRIBUTES && (attributes & FILE_ATTRIBUTE_DIRECTORY);
}

static int is_executable(const char *path) {
    DWORD attributes = GetFileAttributesA(path);
    return attributes != INVALID_FILE_ATTRIBUTES && !(attributes & FILE_ATTRIBUTE_DIRECTORY);
}

/* The home is not given on Windows: Python finds it from pythonXY.dll's folder. */
#define GIVES_PYTHON_HOME 0

/* The process-wide lock and ready flag of the one Python start (see process.c for why): named
 * kernel objects of this process, a mutex and a manual-reset event, which every loader of the
 * process opens by name (created by the first).  Their handles are closed at unload; the
 * objects live while any loader holds them, and a loader loaded after all were unloaded creates
 * them again and finds Python initialised under the lock. */
static HANDLE process_mutex, ready_event;

static int find_process(char *problem, size_t size) {
    if (process_mutex != NULL) return 1; /* (called under the loader's own lock) */
    char name[64];
    snprintf(name, sizeof name, "Local\\greyfmu-python-start-%lu", GetCurrentProcessId());
    HANDLE mutex = CreateMutexA(NULL, FALSE, name);
    snprintf(name, sizeof name, "Local\\greyfmu-python-ready-%lu", GetCurrentProcessId());
    HANDLE event = CreateEventA(NULL, TRUE, FALSE, name);
    if (mutex == NULL || event == NULL) {
        append(problem, size, "cannot create the process-wide lock of the greyfmu loaders (Windows error %lu)",
               GetLastError());
        if (mutex != NULL) CloseHandle(mutex);
        if (event != NULL) CloseHandle(event);
        return 0;
    }
    process_mutex = mutex;
    ready_event = event;
    return 1;
}
static void process_lock(void) { WaitForSingleObject(process_mutex, INFINITE); }
static void process_unlock(void) { ReleaseMutex(process_mutex); }
static int python_ready(void) { return WaitForSingleObject(ready_event, 0) == WAIT_OBJECT_0; }
static void set_python_ready(void) { SetEvent(ready_event); }
static void forget_process(void) {
    if (process_mutex != NULL) CloseHandle(process_mutex);
    if (ready_event != NULL) CloseHandle(ready_event);
    process_mutex = ready_event = NULL;
}

/* The host's SIGINT disposition in the C runtime Python uses (ucrtbase.dll): importing Python's
 * signal module installs Python's handler there when it is the default, and the C runtime's
 * console control handler then swallows Ctrl-C (the handler only sets a flag for Python's main
 * thread).  The loader's own C runtime is another one, so ucrtbase's signal() is called. */
typedef void (*SignalHandler)(int);
typedef struct {
    SignalHandler sigint;
} HostSignals;

static SignalHandler (*python_crt_signal(void))(int, SignalHandler) {
    HMODULE crt = GetModuleHandleA("ucrtbase.dll");
    return crt != NULL ? (SignalHandler(*)(int, SignalHandler))(void *)GetProcAddress(crt, "signal") : NULL;
}

static void save_signals(HostSignals *saved) {
    SignalHandler (*crt_signal)(int, SignalHandler) = python_crt_signal();
    saved->sigint = SIG_DFL; /* a C runtime not loaded yet starts with the default */
    if (crt_signal != NULL) {
        saved->sigint = crt_signal(SIGINT, SIG_DFL);
        crt_signal(SIGINT, saved->sigint);
    }
}

static void restore_signals(const HostSignals *saved) {
    SignalHandler (*crt_signal)(int, SignalHandler) = python_crt_signal();
    if (crt_signal != NULL) crt_signal(SIGINT, saved->sigint);
}

static int run_query(const char *python, const char *script, char **output, char *problem, size_t size) {
    SECURITY_ATTRIBUTES inherit = {sizeof inherit, NULL, TRUE};
    HANDLE read_end, write_end;
    if (!CreatePipe(&read_end, &write_end, &inherit, 0)) {
        append(problem, size, "cannot create a pipe to run %s (Windows error %lu)", python, GetLastError());
        return 0;
    }
    SetHandleInformation(read_end, HANDLE_FLAG_INHERIT, 0);
    HANDLE nul = CreateFileA("NUL", GENERIC_READ, FILE_SHARE_READ | FILE_SHARE_WRITE, &inherit, OPEN_EXISTING, 0, NULL);
    STARTUPINFOA startup = {0};
    startup.cb = sizeof startup;
    startup.dwFlags = STARTF_USESTDHANDLES;
    startup.hStdInput = nul;
    startup.hStdOutput = write_end;
    startup.hStdError = write_end;
    PROCESS_INFORMATION child;
    char command[3 * PATH_MAX];
    snprintf(command, sizeof command, "\"%s\" \"%s\" --query", python, script);
    BOOL started = CreateProcessA(python, command, NULL, NULL, TRUE, CREATE_NO_WINDOW, NULL, NULL, &startup, &child);
    CloseHandle(write_end);
    CloseHandle(nul);
    if (!started) {
        append(problem, size, "cannot run %s (Windows error %lu)", python, GetLastError());
        CloseHandle(read_end);
        return 0;
    }
    /* Read to the end of the output (the child closing its end), keeping OUTPUT_LIMIT bytes and
     * dropping the rest, so a child writing more than the pipe holds never blocks; then wait. */
    size_t capacity = 8192, length = 0;
    char *text = malloc(capacity), scrap[4096];
    ULONGLONG deadline = GetTickCount64() + QUERY_SECONDS * 1000ULL;
    int timed_out = 0;
    for (;;) {
        if (GetTickCount64() >= deadline) { /* also for a child that writes without end */
            timed_out = 1;
            break;
        }
        DWORD available = 0;
        if (!PeekNamedPipe(read_end, NULL, 0, NULL, &available, NULL)) break; /* the child closed its end */
        if (available == 0) {
            WaitForSingleObject(child.hProcess, 20);
            continue;
        }
        if (text != NULL && length + available + 1 > capacity && capacity < OUTPUT_LIMIT) {
            while (length + available + 1 > capacity && capacity < OUTPUT_LIMIT) capacity *= 2;
            char *grown = realloc(text, capacity);
            if (grown == NULL) free(text);
            text = grown;
        }
        size_t room = text != NULL ? capacity - length - 1 : 0;
        char *into = room > 0 ? text + length : scrap;
        DWORD want = (DWORD)(room > 0 ? room : sizeof scrap);
        if (want > available) want = available;
        DWORD got = 0;
        if (!ReadFile(read_end, into, want, &got, NULL)) break;
        if (into != scrap) length += got;
    }
    CloseHandle(read_end); /* before waiting: a child still writing gets a broken pipe, not a full one */
    if (timed_out) TerminateProcess(child.hProcess, 1);
    WaitForSingleObject(child.hProcess, INFINITE);
    CloseHandle(child.hProcess);
    CloseHandle(child.hThread);
    if (text != NULL) text[length] = '\0';
    return query_answer(text, timed_out, python, output, problem, size);
}

#else
/* ------------------------------------------------------------------ Linux */
#include <dlfcn.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <link.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "process.h"

extern char **environ;

#define EXPORT __attribute__((visibility("default")))
#define SEPARATOR '/'
#define PATH_LIST_SEPARATOR ":"
#define PLATFORM_FOLDER "linux64"
#define PLATFORM_FOLDER3 "x86_64-linux" /* FMI 3.0 */
#define LIBRARY_SUFFIX ".so"
#define PYTHON_ON_PATH "python3"

typedef pthread_mutex_t Lock;
#define LOCK_INITIALIZER PTHREAD_MUTEX_INITIALIZER
static void lock(Lock *l) { pthread_mutex_lock(l); }
static void unlock(Lock *l) { pthread_mutex_unlock(l); }

static void *library_open(const char *path, int global, char *problem, size_t size) {
    void *library = dlopen(path, RTLD_NOW | (global ? RTLD_GLOBAL : RTLD_LOCAL));
    if (library == NULL) append(problem, size, "cannot load %s: %s", path, dlerror());
    return library;
}

static void *library_symbol(void *library, const char *name) { return dlsym(library, name); }

/* Whether `object` (a loaded library's file name) itself defines Py_IsInitialized, not through a
 * library it depends on: then it is a libpython. */
static int defines_python(const char *object) {
    void *library = dlopen(object, RTLD_NOLOAD | RTLD_NOW);
    if (library == NULL) return 0;
    Dl_info where;
    void *symbol = dlsym(library, "Py_IsInitialized");
    int defines = symbol != NULL && dladdr(symbol, &where) && where.dli_fname != NULL &&
                  strcmp(where.dli_fname, object) == 0;
    dlclose(library);
    return defines;
}

/* A Python already in this process, initialised or not, however libpython is linked; NULL if none.
 * (Not RTLD_DEFAULT: on glibc that is NULL, which read as "none" and started a second Python.)
 *  - The global scope (dlopen(NULL)): a libpython linked into the executable and exporting its
 *    symbols (Debian's and Ubuntu's /usr/bin/python3), or a shared libpython loaded RTLD_GLOBAL.
 *  - Otherwise each loaded object in turn: a shared libpython loaded RTLD_LOCAL (a host that
 *    embeds Python) is re-opened RTLD_GLOBAL, so pythonfmu-export.so, which does not link
 *    libpython, resolves its Python symbols there. */
static void *loaded_python(void) {
    void *global = dlopen(NULL, RTLD_NOW);
    if (global == NULL) return NULL;
    if (dlsym(global, "Py_IsInitialized") != NULL) return global;
    struct link_map *object = NULL;
    if (dlinfo(global, RTLD_DI_LINKMAP, &object) != 0) return NULL;
    for (; object != NULL; object = object->l_next)
        if (object->l_name != NULL && *object->l_name && defines_python(object->l_name))
            return dlopen(object->l_name, RTLD_NOLOAD | RTLD_NOW | RTLD_GLOBAL);
    return NULL;
}

/* Whether the file `path` is the libpython `python` (from loaded_python) already in this process. */
static int is_loaded_python(void *python, const char *path) {
    void *library = dlopen(path, RTLD_NOLOAD | RTLD_NOW);
    int same = library != NULL && dlsym(library, "Py_IsInitialized") == dlsym(python, "Py_IsInitialized");
    if (library != NULL) dlclose(library);
    return same;
}

static int library_path(char *path, size_t size) {
    Dl_info info;
    char *resolved = NULL; /* realpath's own allocation: no PATH_MAX buffer on the host's stack */
    if (!dladdr((void *)&library_path, &info) || info.dli_fname == NULL ||
        (resolved = realpath(info.dli_fname, NULL)) == NULL)
        return 0;
    int fits = strlen(resolved) < size;
    if (fits) memcpy(path, resolved, strlen(resolved) + 1);
    free(resolved);
    return fits;
}

static int is_directory(const char *path) {
    struct stat status;
    return stat(path, &status) == 0 && S_ISDIR(status.st_mode);
}

static int is_executable(const char *path) {
    struct stat status;
    return stat(path, &status) == 0 && S_ISREG(status.st_mode) && access(path, X_OK) == 0;
}

/* The candidate's home (base prefix) is given to Python before it starts (Py_SetPythonHome, not
 * PYTHONHOME: setenv races every getenv of a multithreaded host). */
#define GIVES_PYTHON_HOME 1

/* The process-wide lock and ready flag of the one Python start: greyfmu-process.so's structure
 * (process.c says why and how every loader finds the same one). */
static GreyfmuProcess *shared_process;

static int find_process(char *problem, size_t size) {
    if (__atomic_load_n(&shared_process, __ATOMIC_ACQUIRE) != NULL) return 1;
    GreyfmuProcess *found = dlsym(RTLD_DEFAULT, GREYFMU_PROCESS_SYMBOL);
    if (found == NULL) {
        char *path = malloc(PATH_MAX + 64);
        if (path == NULL || !library_path(path, PATH_MAX)) {
            append(problem, size, "cannot locate the loader's own binary to load %s", GREYFMU_PROCESS_LIBRARY);
            free(path);
            return 0;
        }
        strcpy(strrchr(path, '/') + 1, GREYFMU_PROCESS_LIBRARY);
        void *library = dlopen(path, RTLD_NOW | RTLD_GLOBAL | RTLD_NODELETE); /* never closed: it stays */
        if (library == NULL) append(problem, size, "cannot load %s (the FMU is incomplete): %s", path, dlerror());
        free(path);
        if (library == NULL) return 0;
        found = dlsym(RTLD_DEFAULT, GREYFMU_PROCESS_SYMBOL);
        if (found == NULL) {
            append(problem, size, "%s defines no %s", GREYFMU_PROCESS_LIBRARY, GREYFMU_PROCESS_SYMBOL);
            return 0;
        }
    }
    __atomic_store_n(&shared_process, found, __ATOMIC_RELEASE);
    return 1;
}
static void process_lock(void) { pthread_mutex_lock(&shared_process->lock); }
static void process_unlock(void) { pthread_mutex_unlock(&shared_process->lock); }
static int python_ready(void) { return __atomic_load_n(&shared_process->python_ready, __ATOMIC_ACQUIRE); }
static void set_python_ready(void) { __atomic_store_n(&shared_process->python_ready, 1, __ATOMIC_RELEASE); }
static void forget_process(void) {} /* the structure outlives this loader (RTLD_NODELETE) */

/* The host's signal dispositions, saved before a call into Python and put back after it where
 * Python changed them: importing Python's signal module installs Python's SIGINT handler when
 * the disposition is the default (signalmodule.c), and that handler only sets a flag for Python's
 * main thread, so a C host without a handler no longer died on Ctrl-C (and if the thread that
 * started Python had ended, Ctrl-C was lost). */
enum { SAVED_SIGNALS = 32 }; /* the standard signals 1..31 */
typedef struct {
    struct sigaction action[SAVED_SIGNALS];
} HostSignals;

static void save_signals(HostSignals *saved) {
    for (int number = 1; number < SAVED_SIGNALS; number++)
        if (number != SIGKILL && number != SIGSTOP) sigaction(number, NULL, &saved->action[number]);
}

static void restore_signals(const HostSignals *saved) {
    for (int number = 1; number < SAVED_SIGNALS; number++) {
        struct sigaction now;
        if (number == SIGKILL || number == SIGSTOP || sigaction(number, NULL, &now) != 0) continue;
        if (now.sa_handler != saved->action[number].sa_handler || now.sa_flags != saved->action[number].sa_flags)
            sigaction(number, &saved->action[number], NULL);
    }
}

/* Seconds on CLOCK_MONOTONIC (a wall-clock change moves no deadline). */
static double monotonic_seconds(void) {
    struct timespec now;
    clock_gettime(CLOCK_MONOTONIC, &now);
    return (double)now.tv_sec + (double)now.tv_nsec * 1e-9;
}

static int run_query(const char *python, const char *script, char **output, char *problem, size_t size) {
    int pipe_ends[2];
    if (pipe2(pipe_ends, O_CLOEXEC) != 0) { /* no other child the host starts inherits them */
        append(problem, size, "cannot create a pipe to run %s (%s)", python, strerror(errno));
        return 0;
    }
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, pipe_ends[1], STDOUT_FILENO);
    posix_spawn_file_actions_adddup2(&actions, pipe_ends[1], STDERR_FILENO);
    posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", 0, 0);
    char *argv[] = {(char *)python, (char *)script, "--query", NULL};
    pid_t child;
    int spawned = posix_spawn(&child, python, &actions, NULL, argv, environ);
    posix_spawn_file_actions_destroy(&actions);
    close(pipe_ends[1]);
    if (spawned != 0) {
        close(pipe_ends[0]);
        append(problem, size, "cannot run %s (%s)", python, strerror(spawned));
        return 0;
    }
    /* Read to the end of the output, keeping OUTPUT_LIMIT bytes; a signal interrupting poll or
     * read (EINTR) is retried against the same monotonic deadline. */
    size_t capacity = 8192, length = 0;
    char *text = malloc(capacity), scrap[4096];
    double deadline = monotonic_seconds() + QUERY_SECONDS;
    int timed_out = 0;
    for (;;) {
        double left = deadline - monotonic_seconds();
        if (left <= 0) {
            timed_out = 1;
            break;
        }
        struct pollfd ready = {pipe_ends[0], POLLIN, 0};
        int polled = poll(&ready, 1, (int)(left * 1000) + 1);
        if (polled < 0 && errno == EINTR) continue;
        if (polled < 0) break;
        if (polled == 0) continue; /* the deadline, checked above */
        if (text != NULL && length + 4096 > capacity && capacity < OUTPUT_LIMIT) {
            char *grown = realloc(text, capacity *= 2);
            if (grown == NULL) free(text);
            text = grown;
        }
        size_t room = text != NULL ? capacity - length - 1 : 0;
        ssize_t got = room > 0 ? read(pipe_ends[0], text + length, room) : read(pipe_ends[0], scrap, sizeof scrap);
        if (got < 0 && errno == EINTR) continue;
        if (got <= 0) break;
        if (room > 0) length += (size_t)got;
    }
    close(pipe_ends[0]);
    if (text != NULL) text[length] = '\0';
    if (timed_out) kill(child, SIGKILL);
    int status = 0;
    while (waitpid(child, &status, 0) < 0 && errno == EINTR) {
    }
    return query_answer(text, timed_out, python, output, problem, size);
}
#endif

#endif
