"""Small FMI 2.0 and FMI 3.0 Co-Simulation FMUs compiled from C at test time (gcc), for the
behaviours pythonfmu cannot produce: fmi2DoStep returning Discard with fmi2LastSuccessfulTime
and fmi2Terminated, fmi3DoStep returning OK with terminateSimulation = true.

A test gives the model description and the model's C body; the body defines

* ``static void calculate(S *s)``: the outputs from the inputs and states (called before every
  get, so an output that depends on an input is direct feedthrough);
* ``static int step(S *s, double t, double h)``: advance from t by h, return the FMI status
  (0 OK, 2 Discard); it may set ``s->terminate`` and lower ``s->last`` (the last successful time, t + h
  unless it does).

An FMI 2.0 body may log through the host's logger: ``s->callbacks`` is the
fmi2CallbackFunctions given at instantiation (its first member the variadic logger, its last the
componentEnvironment), ``s->name`` the instance name.

Variables are addressed by value reference into ``s->r`` (Real/Float64), ``s->i``
(Integer/Int32), ``s->b`` (Boolean) and, FMI 3.0 only, ``s->f`` (Float32) and ``s->l``
(Int8..UInt64, Enumeration), 64 of each, and Binary values of up to 16 bytes in
``s->bytes[vr]`` (length ``s->nbytes[vr]``).  An FMI 3.0 array variable at ``vr`` with ``s->extent[vr]``
values (set by the body; 0 is a scalar) holds them at ``vr``, ``vr + 1``, ... (row-major, as the
FMI 3.0 functions pass them).  The model description's start values are
the body's business (``static void start(S *s)``, called at instantiation).  Every other FMI
function of the interface is a stub returning Error, so fmpy finds all the symbols it loads.
"""
from __future__ import annotations

import re
import subprocess
import zipfile
from pathlib import Path

from fmpy.fmi2 import FMU2Model, FMU2Slave
from fmpy.fmi3 import FMU3Model, FMU3Slave

COMMON = r"""
#include <stdlib.h>
#include <string.h>
#include <stdbool.h>
typedef struct { double r[64]; int i[64]; int b[64]; float f[64]; long long l[64];
                 unsigned char bytes[64][16]; size_t nbytes[64]; double time; int terminate; double last;
                 const void *callbacks; char name[64]; size_t extent[64]; } S;
/* FMI 3.0 arrays: the variable at vr has extent[vr] values (0: a scalar), at vr, vr + 1, ... */
#define EXTENT(s, r) ((s)->extent[r] ? (s)->extent[r] : 1)
#define EACH_VALUE(s, vr, n) for (size_t k = 0, j = 0; k < (n); k++) for (size_t e = 0; e < EXTENT(s, (vr)[k]); e++, j++)
/* FMI 3.0 §2.2.6.2: nValues is the number of values behind the value references; another count is an error */
#define COUNT_OK(s, vr, n, nv) do { size_t t_ = 0; for (size_t k_ = 0; k_ < (n); k_++) t_ += EXTENT(s, (vr)[k_]); \
                                    if (t_ != (nv)) return 3; } while (0)
"""

#: the FMI 3.0 getters and setters of the other numeric types: Float32 in ``s->f``, the
#: integer types (Int8..UInt64, and Enumeration, an Int64) in ``s->l``
FMI3_OTHER_TYPES = "".join(
    f"int fmi3Get{t}(void *c, const VR vr[], size_t n, {ct} v[], size_t nv) {{\n"
    f"    S *s = c; COUNT_OK(s, vr, n, nv); calculate(s); EACH_VALUE(s, vr, n) v[j] = ({ct}) s->{a}[vr[k] + e]; return 0; }}\n"
    f"int fmi3Set{t}(void *c, const VR vr[], size_t n, const {ct} v[], size_t nv) {{\n"
    f"    S *s = c; COUNT_OK(s, vr, n, nv); EACH_VALUE(s, vr, n) s->{a}[vr[k] + e] = v[j]; return 0; }}\n"
    for t, ct, a in [("Float32", "float", "f"), ("Int8", "signed char", "l"), ("UInt8", "unsigned char", "l"),
                     ("Int16", "short", "l"), ("UInt16", "unsigned short", "l"), ("UInt32", "unsigned int", "l"),
                     ("Int64", "long long", "l"), ("UInt64", "unsigned long long", "l")])

FMI2 = COMMON + r"""
typedef unsigned int VR;
typedef struct { int newDiscreteStatesNeeded, terminateSimulation, nominalsOfContinuousStatesChanged,
                 valuesOfContinuousStatesChanged, nextEventTimeDefined; double nextEventTime; } EventInfo;
const char *fmi2GetTypesPlatform(void) { return "default"; }
const char *fmi2GetVersion(void) { return "2.0"; }
static void start(S *s);
static void calculate(S *s);
static int step(S *s, double t, double h);
void *fmi2Instantiate(const char *n, int type, const char *guid, const char *res, const void *cb, int vis, int log) {
    S *s = calloc(1, sizeof(S)); s->callbacks = cb; strncpy(s->name, n ? n : "", 63); start(s); return s; }
void fmi2FreeInstance(void *c) { free(c); }
int fmi2SetDebugLogging(void *c, int on, size_t n, const char *cats[]) { return 0; }
int fmi2SetupExperiment(void *c, int tolDef, double tol, double t0, int stopDef, double stop) {
    ((S *)c)->time = t0; ((S *)c)->last = t0; return 0; }
int fmi2EnterInitializationMode(void *c) { return 0; }
int fmi2ExitInitializationMode(void *c) { return 0; }
int fmi2Terminate(void *c) { return 0; }
int fmi2Reset(void *c) { return 3; }
int fmi2GetReal(void *c, const VR vr[], size_t n, double v[]) {
    S *s = c; calculate(s); for (size_t k = 0; k < n; k++) v[k] = s->r[vr[k]]; return 0; }
int fmi2GetInteger(void *c, const VR vr[], size_t n, int v[]) {
    S *s = c; calculate(s); for (size_t k = 0; k < n; k++) v[k] = s->i[vr[k]]; return 0; }
int fmi2GetBoolean(void *c, const VR vr[], size_t n, int v[]) {
    S *s = c; calculate(s); for (size_t k = 0; k < n; k++) v[k] = s->b[vr[k]]; return 0; }
int fmi2SetReal(void *c, const VR vr[], size_t n, const double v[]) {
    S *s = c; for (size_t k = 0; k < n; k++) s->r[vr[k]] = v[k]; return 0; }
int fmi2SetInteger(void *c, const VR vr[], size_t n, const int v[]) {
    S *s = c; for (size_t k = 0; k < n; k++) s->i[vr[k]] = v[k]; return 0; }
int fmi2SetBoolean(void *c, const VR vr[], size_t n, const int v[]) {
    S *s = c; for (size_t k = 0; k < n; k++) s->b[vr[k]] = v[k]; return 0; }
int fmi2DoStep(void *c, double t, double h, int noPrior) {
    S *s = c; s->last = t + h; int status = step(s, t, h); s->time = s->last; return status; }
int fmi2GetRealStatus(void *c, int kind, double *v) {
    if (kind != 2) return 3; *v = ((S *)c)->last; return 0; }   /* fmi2LastSuccessfulTime */
int fmi2GetBooleanStatus(void *c, int kind, int *v) {
    if (kind != 3) return 3; *v = ((S *)c)->terminate; return 0; }   /* fmi2Terminated */
"""

FMI3 = COMMON + r"""
typedef unsigned int VR;
const char *fmi3GetVersion(void) { return "3.0"; }
static void start(S *s);
static void calculate(S *s);
static int step(S *s, double t, double h);
void *fmi3InstantiateCoSimulation(const char *n, const char *token, const char *res, bool vis, bool log,
        bool eventMode, bool earlyReturn, const VR req[], size_t nreq, void *env, void *logger, void *inter) {
    S *s = calloc(1, sizeof(S)); start(s); return s; }
void fmi3FreeInstance(void *c) { free(c); }
int fmi3SetDebugLogging(void *c, bool on, size_t n, const char *cats[]) { return 0; }
int fmi3EnterInitializationMode(void *c, bool tolDef, double tol, double t0, bool stopDef, double stop) {
    ((S *)c)->time = t0; ((S *)c)->last = t0; return 0; }
int fmi3ExitInitializationMode(void *c) { return 0; }
int fmi3Terminate(void *c) { return 0; }
int fmi3Reset(void *c) { return 3; }
int fmi3GetFloat64(void *c, const VR vr[], size_t n, double v[], size_t nv) {
    S *s = c; COUNT_OK(s, vr, n, nv); calculate(s); EACH_VALUE(s, vr, n) v[j] = s->r[vr[k] + e]; return 0; }
int fmi3GetInt32(void *c, const VR vr[], size_t n, int v[], size_t nv) {
    S *s = c; COUNT_OK(s, vr, n, nv); calculate(s); EACH_VALUE(s, vr, n) v[j] = s->i[vr[k] + e]; return 0; }
int fmi3GetBoolean(void *c, const VR vr[], size_t n, bool v[], size_t nv) {
    S *s = c; COUNT_OK(s, vr, n, nv); calculate(s); EACH_VALUE(s, vr, n) v[j] = s->b[vr[k] + e]; return 0; }
int fmi3SetFloat64(void *c, const VR vr[], size_t n, const double v[], size_t nv) {
    S *s = c; COUNT_OK(s, vr, n, nv); EACH_VALUE(s, vr, n) s->r[vr[k] + e] = v[j]; return 0; }
int fmi3SetInt32(void *c, const VR vr[], size_t n, const int v[], size_t nv) {
    S *s = c; COUNT_OK(s, vr, n, nv); EACH_VALUE(s, vr, n) s->i[vr[k] + e] = v[j]; return 0; }
int fmi3SetBoolean(void *c, const VR vr[], size_t n, const bool v[], size_t nv) {
    S *s = c; COUNT_OK(s, vr, n, nv); EACH_VALUE(s, vr, n) s->b[vr[k] + e] = v[j]; return 0; }
int fmi3DoStep(void *c, double t, double h, bool noPrior, bool *event, bool *terminate, bool *early, double *last) {
    S *s = c; s->last = t + h; int status = step(s, t, h); s->time = s->last;
    *event = false; *early = false; *terminate = s->terminate; *last = s->last; return status; }
int fmi3GetBinary(void *c, const VR vr[], size_t n, size_t sizes[], const unsigned char *v[], size_t nv) {
    S *s = c; calculate(s);
    for (size_t k = 0; k < n; k++) { sizes[k] = s->nbytes[vr[k]]; v[k] = s->bytes[vr[k]]; } return 0; }
int fmi3SetBinary(void *c, const VR vr[], size_t n, const size_t sizes[], const unsigned char *const v[], size_t nv) {
    S *s = c;
    for (size_t k = 0; k < n; k++) {
        size_t m = sizes[k] < 16 ? sizes[k] : 16; memcpy(s->bytes[vr[k]], v[k], m); s->nbytes[vr[k]] = m; }
    return 0; }
""" + FMI3_OTHER_TYPES

#: FMI 3.0 Model Exchange (``model_exchange=True``): the body also defines ``#define NX``
#: (states in ``s->r[0..NX-1]``), ``NZ``, ``static void derivatives(S *s, double dx[])``,
#: ``static void indicators(S *s, double z[])`` and ``static void event(S *s)`` (Event Mode).
FMI3_ME = r"""
static void derivatives(S *s, double dx[]);
static void indicators(S *s, double z[]);
static void event(S *s);
void *fmi3InstantiateModelExchange(const char *n, const char *token, const char *res, bool vis, bool log,
        void *env, void *logger) { S *s = calloc(1, sizeof(S)); start(s); return s; }
int fmi3EnterContinuousTimeMode(void *c) { return 0; }
int fmi3EnterEventMode(void *c) { return 0; }
int fmi3SetTime(void *c, double t) { ((S *)c)->time = t; return 0; }
int fmi3GetNumberOfContinuousStates(void *c, size_t *n) { *n = NX; return 0; }
int fmi3GetNumberOfEventIndicators(void *c, size_t *n) { *n = NZ; return 0; }
int fmi3SetContinuousStates(void *c, const double x[], size_t nx) {
    S *s = c; for (size_t k = 0; k < nx; k++) s->r[k] = x[k]; return 0; }
int fmi3GetContinuousStates(void *c, double x[], size_t nx) {
    S *s = c; for (size_t k = 0; k < nx; k++) x[k] = s->r[k]; return 0; }
int fmi3GetContinuousStateDerivatives(void *c, double dx[], size_t nx) { derivatives((S *)c, dx); return 0; }
int fmi3GetEventIndicators(void *c, double z[], size_t nz) { indicators((S *)c, z); return 0; }
int fmi3GetNominalsOfContinuousStates(void *c, double x[], size_t nx) {
    for (size_t k = 0; k < nx; k++) x[k] = 1.0; return 0; }
int fmi3CompletedIntegratorStep(void *c, bool noPrior, bool *enterEventMode, bool *terminate) {
    *enterEventMode = false; *terminate = false; return 0; }
#ifndef CUSTOM_UPDATE
int fmi3UpdateDiscreteStates(void *c, bool *needUpdate, bool *terminate, bool *nominalsChanged, bool *valuesChanged,
        bool *nextDefined, double *next) {
    event((S *)c); *needUpdate = false; *terminate = false; *nominalsChanged = false; *valuesChanged = true;
    *nextDefined = false; *next = 0.0; return 0; }
#endif
"""

#: FMI 2.0 Model Exchange (``model_exchange=True``), the same body functions as `FMI3_ME`; a body
#: that ``#define``s ``CUSTOM_UPDATE`` writes its own fmi2NewDiscreteStates (fmi3UpdateDiscreteStates
#: for FMI 3.0), e.g. one that bends the standard.
FMI2_ME = r"""
static void derivatives(S *s, double dx[]);
static void indicators(S *s, double z[]);
static void event(S *s);
int fmi2EnterEventMode(void *c) { return 0; }
int fmi2EnterContinuousTimeMode(void *c) { return 0; }
int fmi2SetTime(void *c, double t) { ((S *)c)->time = t; return 0; }
int fmi2SetContinuousStates(void *c, const double x[], size_t nx) {
    S *s = c; for (size_t k = 0; k < nx; k++) s->r[k] = x[k]; return 0; }
int fmi2GetContinuousStates(void *c, double x[], size_t nx) {
    S *s = c; for (size_t k = 0; k < nx; k++) x[k] = s->r[k]; return 0; }
int fmi2GetDerivatives(void *c, double dx[], size_t nx) { derivatives((S *)c, dx); return 0; }
int fmi2GetEventIndicators(void *c, double z[], size_t nz) { indicators((S *)c, z); return 0; }
int fmi2GetNominalsOfContinuousStates(void *c, double x[], size_t nx) {
    for (size_t k = 0; k < nx; k++) x[k] = 1.0; return 0; }
int fmi2CompletedIntegratorStep(void *c, int noPrior, int *enterEventMode, int *terminate) {
    *enterEventMode = 0; *terminate = 0; return 0; }
#ifndef CUSTOM_UPDATE
int fmi2NewDiscreteStates(void *c, EventInfo *info) {
    event((S *)c); info->newDiscreteStatesNeeded = 0; info->terminateSimulation = 0;
    info->nominalsOfContinuousStatesChanged = 0; info->valuesOfContinuousStatesChanged = 1;
    info->nextEventTimeDefined = 0; info->nextEventTime = 0.0; return 0; }
#endif
"""

PLATFORM = {"2.0": "linux64", "3.0": "x86_64-linux"}


def fmi2_description(name: str, variables: list[tuple[str, int, str, float | None]],
                     dependencies: dict[str, list[str]] | None, guid: str) -> str:
    """An FMI 2.0 Co-Simulation model description for `build_c_fmu`: ``variables`` are (name, value
    reference, causality "input"/"output"/"parameter", start or None), all Real; each output lists
    the inputs it depends on (``dependencies``: output -> input names), or, with ``dependencies``
    None, no ``dependencies`` attribute at all (which per FMI means "depends on every input")."""
    rows, unknowns = [], []
    index = {var: i for i, (var, *_) in enumerate(variables, 1)}
    for var, vr, causality, start in variables:
        attrs = {"output": 'variability="continuous"', "input": 'variability="continuous"',
                 "parameter": 'variability="fixed" initial="exact"'}[causality]
        real = "<Real/>" if start is None else f'<Real start="{start}"/>'
        rows.append(f'<ScalarVariable name="{var}" valueReference="{vr}" causality="{causality}" {attrs}>{real}'
                    '</ScalarVariable>')
        if causality == "output":
            if dependencies is None:
                unknowns.append(f'<Unknown index="{index[var]}"/>')
            else:
                deps = " ".join(str(index[d]) for d in dependencies.get(var, ()))
                unknowns.append(f'<Unknown index="{index[var]}" dependencies="{deps}"/>')
    return ('<?xml version="1.0" encoding="UTF-8"?>\n'
            f'<fmiModelDescription fmiVersion="2.0" modelName="{name}" guid="{guid}" numberOfEventIndicators="0">'
            f'<CoSimulation modelIdentifier="{name}" canHandleVariableCommunicationStepSize="true"/>'
            f'<ModelVariables>{"".join(rows)}</ModelVariables>'
            f'<ModelStructure><Outputs>{"".join(unknowns)}</Outputs></ModelStructure></fmiModelDescription>\n')


def build_c_fmu(dest: Path, identifier: str, model_description: str, body: str, fmi: str = "2.0",
                model_exchange: bool = False) -> Path:
    """Compile ``body`` (see the module docstring) into ``dest/<identifier>.fmu`` with
    ``model_description`` as its modelDescription.xml; ``model_exchange``: the Model Exchange
    functions too (`FMI2_ME`, `FMI3_ME`)."""
    prelude, apis = (FMI2, [FMU2Slave, FMU2Model]) if fmi == "2.0" else (FMI3, [FMU3Slave, FMU3Model])
    prefix = "fmi2" if fmi == "2.0" else "fmi3"
    source = prelude + body + ((FMI2_ME if fmi == "2.0" else FMI3_ME) if model_exchange else "")
    defined = set(re.findall(rf"\b({prefix}\w+)\s*\(", source))
    names = sorted({name for api in apis for name in dir(api) if name.startswith(prefix)} - defined)
    stubs = "".join(f"int {name}() {{ return 3; }}\n" for name in names)
    build = dest / f"{identifier}_build"
    build.mkdir(parents=True, exist_ok=True)
    (build / "model.c").write_text(source + stubs)
    library = build / f"{identifier}.so"
    subprocess.run(["gcc", "-std=gnu11", "-shared", "-fPIC", "-O1", "-o", str(library), str(build / "model.c")],
                   check=True, capture_output=True, text=True)
    fmu = dest / f"{identifier}.fmu"
    with zipfile.ZipFile(fmu, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("modelDescription.xml", model_description)
        archive.write(library, f"binaries/{PLATFORM[fmi]}/{identifier}.so")
    return fmu
