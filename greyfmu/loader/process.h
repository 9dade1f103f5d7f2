/* The structure every greyfmu loader in a process shares (process.c; Linux). */
#ifndef GREYFMU_LOADER_PROCESS_H
#define GREYFMU_LOADER_PROCESS_H

#include <pthread.h>

#define GREYFMU_PROCESS_SYMBOL "greyfmu_process_v1"
#define GREYFMU_PROCESS_LIBRARY "greyfmu-process.so"

typedef struct {
    unsigned size;        /* sizeof(GreyfmuProcess) of the copy that defines it: fields are only appended */
    pthread_mutex_t lock; /* held by a loader while it looks for, starts or sets up Python */
    int python_ready;     /* a Python runs in the process and is set up (__atomic_load_n/__atomic_store_n) */
} GreyfmuProcess;

#endif
