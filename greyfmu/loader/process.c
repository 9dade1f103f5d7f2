/* greyfmu-process.so: what every greyfmu loader in a process shares (Linux; fmi2_loader.c,
 * platform.h process_state).  Shipped in each FMU beside its loader as
 * binaries/linux64/greyfmu-process.so.
 *
 * Python starts once per process, however many FMU binaries of ours the host loads: a lock and
 * a ready flag kept per binary let two FMUs' first instantiations on two threads both start
 * Python (Fatal Python error, SIGSEGV, "cannot import numpy": 8 of 10 trials of a C host making
 * the first instances of four FMUs at once).  The first loader that needs it loads this object
 * RTLD_GLOBAL | RTLD_NODELETE; every loader then finds the one structure through
 * dlsym(RTLD_DEFAULT, GREYFMU_PROCESS_SYMBOL), the first definition in the process's global
 * scope.  That scope only grows by appending and a NODELETE object never leaves it, so all
 * loaders agree on the same structure even when two load their own copy at the same moment
 * (each finds whichever was appended first), and it outlives every FMU binary the host unloads.
 * Only the one data symbol is exported: the loader itself (which exports the fmi2 functions) is
 * never made global, so it cannot interpose on another FMU's functions.
 *
 * The layout is append-only (`size` says how much of it the copy found has); a change that is
 * not an addition takes a new symbol name.
 */
#include "process.h"

__attribute__((visibility("default"))) GreyfmuProcess greyfmu_process_v1 = {
    sizeof(GreyfmuProcess), PTHREAD_MUTEX_INITIALIZER, 0};
