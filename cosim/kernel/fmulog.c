/* The FMI 2.0 logger the master gives FMUs (cosim/run/instances/fmi2.py): an FMU's message is a
 * printf format with its arguments (fmi2CallbackLogger is variadic, FMI 2.0 §2.1.5), which ctypes
 * cannot read, so this C function formats it and hands the text to the master's Python callback
 * (cosim_fmi2_log_target).  It formats only what it can format safely, and otherwise hands the
 * message over verbatim (issue 41: fmpy's proxy, a plain vsnprintf, dies of SIGSEGV on a
 * third-party FMU's "%s%s%s%s%s%n%n%n 100%% end" sent without arguments).
 *
 * No ABI lets a callee count the variadic arguments it was given, so "no argument" is recognised
 * where it shows.  The message is handed over verbatim when it holds
 *   - %n (a write through an argument: never made, whatever the arguments),
 *   - a %s whose argument is NULL, not readable memory (checked with process_vm_readv on this
 *     process, which fails with EFAULT instead of faulting), or not text (a control character
 *     within it), which is what a missing argument looks like,
 *   - a conversion this formatter does not make: positional arguments (%1$s), wide characters
 *     (%ls, %lc), an unknown conversion character, a specification cut off at the end,
 *   - the space flag ("50% done", "100% complete": text with a percent sign, not a format).
 * Everything else is formatted one conversion at a time with snprintf and its own argument, into
 * a buffer of COSIM_LOG_MAX bytes (a longer message is cut).  A number conversion without its
 * argument prints whatever the register or stack slot holds, as any printf does: it cannot crash.
 * Where process_vm_readv is missing (not Linux, or refused by a sandbox) a %s is never followed:
 * such messages are handed over verbatim.  Without this library (no compiler at install) the
 * master's callback receives every message verbatim (cosim/run/instances/fmi2.py).
 */
#ifndef _GNU_SOURCE
#define _GNU_SOURCE
#endif
#include <errno.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#ifdef __linux__
#include <sys/uio.h>
#include <unistd.h>
#endif

#define COSIM_LOG_MAX 4096

typedef void (*cosim_log_target)(void *environment, const char *instance, int status, const char *category,
                                 const char *message);

static cosim_log_target target = NULL;

void cosim_fmi2_log_target(cosim_log_target callback) { target = callback; }

/* Copy the string at `text` (at most `limit` bytes, to its NUL) into `copy`, reading it without
 * touching it directly; 0 when it is not readable, not NUL-terminated within `limit`, or holds a
 * control character (not text); else its length + 1. */
static size_t read_text(const char *text, char *copy, size_t limit) {
#ifdef __linux__
    size_t done = 0;
    pid_t self = getpid();
    const long page = sysconf(_SC_PAGESIZE) > 0 ? sysconf(_SC_PAGESIZE) : 4096;
    while (done < limit) {
        uintptr_t at = (uintptr_t) text + done;
        size_t chunk = (size_t) page - at % (size_t) page;  /* never across a page: a partial read is all or nothing */
        if (chunk > limit - done) chunk = limit - done;
        struct iovec local = {copy + done, chunk}, remote = {(void *) at, chunk};
        if (process_vm_readv(self, &local, 1, &remote, 1, 0) != (ssize_t) chunk) return 0;
        for (size_t k = done; k < done + chunk; k++) {
            unsigned char c = (unsigned char) copy[k];
            if (c == 0) return k + 1;
            if ((c < 0x20 && c != '\t' && c != '\n' && c != '\r') || c == 0x7f) return 0;
        }
        done += chunk;
    }
    return 0;
#else
    (void) text; (void) copy; (void) limit;
    return 0;
#endif
}

/* Append `text` (n bytes) to out[*used], keeping a NUL; beyond the buffer it is cut. */
static void append(char *out, size_t size, size_t *used, const char *text, size_t n) {
    if (*used + 1 >= size) return;
    if (n > size - 1 - *used) n = size - 1 - *used;
    memcpy(out + *used, text, n);
    *used += n;
    out[*used] = 0;
}

/* Format `format` with `args` into out (size bytes); 0 when the message must be shown verbatim. */
static int format_safely(char *out, size_t size, const char *format, va_list args) {
    char text[COSIM_LOG_MAX], piece[COSIM_LOG_MAX], spec[64];   /* on the stack: FMUs log from any thread */
    size_t used = 0;
    out[0] = 0;
    for (const char *p = format; *p;) {
        if (*p != '%') {
            const char *next = strchr(p, '%');
            size_t n = next ? (size_t) (next - p) : strlen(p);
            append(out, size, &used, p, n);
            p += n;
            continue;
        }
        if (p[1] == '%') { append(out, size, &used, "%", 1); p += 2; continue; }
        /* %[flags][width][.precision][length]conversion */
        const char *q = p + 1;
        size_t s = 0;
        spec[s++] = '%';
        int star_width = 0, star_precision = 0;
        while (*q && strchr("-+#0'", *q)) { if (s < 40) spec[s++] = *q; q++; }
        if (*q == ' ') return 0;                               /* "50% done": text, not a format */
        if (*q == '*') { star_width = 1; spec[s++] = '*'; q++; }
        else while (*q >= '0' && *q <= '9') { if (s < 40) spec[s++] = *q; q++; }
        if (*q == '$') return 0;                               /* positional arguments */
        if (*q == '.') {
            spec[s++] = *q++;
            if (*q == '*') { star_precision = 1; spec[s++] = '*'; q++; }
            else while (*q >= '0' && *q <= '9') { if (s < 50) spec[s++] = *q; q++; }
        }
        if (s >= 50) return 0;                                  /* a width of 40 digits: not a format */
        int longs = 0, half = 0, size_t_ = 0, long_double = 0;
        for (;; q++) {
            if (*q == 'l') longs++;
            else if (*q == 'h') half++;
            else if (*q == 'z' || *q == 'j' || *q == 't') size_t_ = *q;
            else if (*q == 'L' || *q == 'q') long_double = 1;
            else break;
        }
        char conversion = *q;
        if (conversion == 0 || conversion == 'n' || !strchr("diouxXcseEfFgGaAp", conversion)) return 0;
        if (longs && (conversion == 's' || conversion == 'c')) return 0;   /* wide characters */
        int width = star_width ? va_arg(args, int) : 0, precision = star_precision ? va_arg(args, int) : 0;
        if (width > 256 || width < -256 || precision > COSIM_LOG_MAX) return 0;
        int n = 0;
        spec[s] = 0;
        if (conversion == 's') {
            const char *arg = va_arg(args, const char *);
            if (arg == NULL || !read_text(arg, text, sizeof text)) return 0;
            spec[s++] = 's'; spec[s] = 0;
            if (star_width && star_precision) n = snprintf(piece, sizeof piece, spec, width, precision, text);
            else if (star_width || star_precision) n = snprintf(piece, sizeof piece, spec, star_width ? width : precision, text);
            else n = snprintf(piece, sizeof piece, spec, text);
        } else {
            /* the length modifier as C reads it, then the conversion */
            if (strchr("eEfFgGaA", conversion)) {
                if (long_double) spec[s++] = 'L';
            } else if (size_t_) spec[s++] = (char) size_t_;
            else if (longs >= 2) { spec[s++] = 'l'; spec[s++] = 'l'; }
            else if (longs == 1) spec[s++] = 'l';
            spec[s++] = conversion; spec[s] = 0;
#define PRINT(value) \
            (star_width && star_precision ? snprintf(piece, sizeof piece, spec, width, precision, value) : \
             star_width || star_precision ? snprintf(piece, sizeof piece, spec, star_width ? width : precision, value) : \
             snprintf(piece, sizeof piece, spec, value))
            if (strchr("eEfFgGaA", conversion)) {
                if (long_double) { long double v = va_arg(args, long double); n = PRINT(v); }
                else { double v = va_arg(args, double); n = PRINT(v); }
            } else if (conversion == 'p') { void *v = va_arg(args, void *); n = PRINT(v); }
            else if (conversion == 'c') { int v = va_arg(args, int); n = PRINT(v); }
            else if (size_t_) { size_t v = va_arg(args, size_t); n = PRINT(v); }
            else if (longs >= 2) { long long v = va_arg(args, long long); n = PRINT(v); }
            else if (longs == 1) { long v = va_arg(args, long); n = PRINT(v); }
            else { int v = va_arg(args, int); n = PRINT(v); }   /* hh and h are promoted to int */
#undef PRINT
            (void) half;
        }
        if (n < 0) return 0;
        append(out, size, &used, piece, (size_t) n < sizeof piece ? (size_t) n : sizeof piece - 1);
        p = q + 1;
    }
    return 1;
}

/* The logger FMUs call (fmi2CallbackLogger). */
void cosim_fmi2_log(void *environment, const char *instance, int status, const char *category,
                    const char *message, ...) {
    char out[COSIM_LOG_MAX];
    if (target == NULL) return;
    if (message == NULL) { target(environment, instance, status, category, ""); return; }
    va_list args;
    va_start(args, message);
    int formatted = format_safely(out, sizeof out, message, args);
    va_end(args);
    target(environment, instance, status, category, formatted ? out : message);
}

/* Format `format` with the arguments as cosim_fmi2_log does, into out (tests: the same function
 * called from C with known arguments); returns 0 when the message would be shown verbatim. */
int cosim_format_log(char *out, size_t size, const char *format, ...) {
    va_list args;
    va_start(args, format);
    int formatted = format_safely(out, size, format, args);
    va_end(args);
    return formatted;
}
