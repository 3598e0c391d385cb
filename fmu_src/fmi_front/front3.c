/*
 * front3.c -- the FMI 3.0 co-simulation functions of the drillstring FMUs' twins
 * (drillstring_fmi2.h; compiled with DS_FMI3 defined, instead of front.c).
 *
 * Each function checks the call against the co-simulation state machine of FMI 3.0, section 4.2
 * (the FMI 2.0 front's, front.c: StepComplete is FMI 3.0's Step Mode, and after a discarded step
 * the instance stays in Step Mode without stepping until a state is restored, as after FMI 2.0's
 * fmi2Discard), converts what FMI 3.0 passes differently (bool Booleans, Int64 enumerations,
 * nValues, the native resource path, the experiment given to fmi3EnterInitializationMode) and
 * hands the rest to machine.c, which the FMI 2.0 front shares: the same checks, statuses and
 * messages, the same pythonfmu slave underneath (which speaks FMI 2.0 to this layer).
 *
 * What the FMU does not provide (model exchange, scheduled execution, event mode, clocks, arrays,
 * the types it has no variables of, derivatives) answers fmi3Error with a message; an
 * instantiation that fails returns NULL with a message, at once.
 */
#include "drillstring_fmi2.h"

#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

/* ---- FMI 3.0 types (fmi3PlatformTypes.h, fmi3FunctionTypes.h of the standard) ---------------- */
typedef void *fmi3Instance;
typedef void *fmi3InstanceEnvironment;
typedef void *fmi3FMUState;
typedef uint32_t fmi3ValueReference;
typedef float fmi3Float32;
typedef double fmi3Float64;
typedef int8_t fmi3Int8;
typedef uint8_t fmi3UInt8;
typedef int16_t fmi3Int16;
typedef uint16_t fmi3UInt16;
typedef int32_t fmi3Int32;
typedef uint32_t fmi3UInt32;
typedef int64_t fmi3Int64;
typedef uint64_t fmi3UInt64;
typedef bool fmi3Boolean;
typedef char fmi3Char;
typedef const fmi3Char *fmi3String;
typedef uint8_t fmi3Byte;
typedef const fmi3Byte *fmi3Binary;
typedef bool fmi3Clock;
typedef enum { fmi3OK, fmi3Warning, fmi3Discard, fmi3Error, fmi3Fatal } fmi3Status;
typedef enum {
    fmi3Independent,
    fmi3Constant,
    fmi3Fixed,
    fmi3Tunable,
    fmi3Discrete,
    fmi3Dependent
} fmi3DependencyKind;
typedef enum {
    fmi3IntervalNotYetKnown,
    fmi3IntervalUnchanged,
    fmi3IntervalChanged
} fmi3IntervalQualifier;
typedef void (*fmi3LogMessageCallback)(fmi3InstanceEnvironment, fmi3Status, fmi3String,
                                       fmi3String);
typedef void (*fmi3ClockUpdateCallback)(fmi3InstanceEnvironment);
typedef void (*fmi3IntermediateUpdateCallback)(fmi3InstanceEnvironment, fmi3Float64, fmi3Boolean,
                                               fmi3Boolean, fmi3Boolean, fmi3Boolean,
                                               fmi3Boolean *, fmi3Float64 *);
typedef void (*fmi3LockPreemptionCallback)(void);
typedef void (*fmi3UnlockPreemptionCallback)(void);

_Static_assert(sizeof(fmi3ValueReference) == sizeof(fmi2ValueReference),
               "value references are passed on as they are");
_Static_assert(sizeof(fmi3Int32) == sizeof(fmi2Integer), "Int32 values are passed on as they are");

#define MASK_SetDebugLogging ST_ANY_LIVE
#define MASK_EnterInitializationMode ST_INSTANTIATED
#define MASK_ExitInitializationMode ST_INITIALIZATION
#define MASK_Terminate (ST_STEP_COMPLETE | ST_STEP_FAILED)
#define MASK_Reset ST_ANY_LIVE
#define MASK_Get (ST_INITIALIZATION | ST_STEP_COMPLETE | ST_STEP_FAILED | ST_TERMINATED)
#define MASK_Set (ST_INSTANTIATED | ST_INITIALIZATION | ST_STEP_COMPLETE)
#define MASK_FMUState ST_ANY_LIVE
#define MASK_DoStep ST_STEP_COMPLETE

static fmi3Status status3(fmi2Status s) { return s == fmi2Pending ? fmi3Error : (fmi3Status)s; }

/* ---- instantiation --------------------------------------------------------------------------- */
EXPORT const char *fmi3GetVersion(void) { return "3.0"; }

/* An instance whose messages reach the host's logMessage (NULL: none). */
static Component *new_instance(fmi3String instanceName, fmi3Boolean loggingOn,
                               fmi3InstanceEnvironment environment, fmi3LogMessageCallback log)
{
    Component *c = ds_new_component(instanceName, loggingOn);
    if (!c) return NULL;
    c->host.componentEnvironment = environment;
    c->log3 = (void (*)(void *, int, const char *, const char *))log;
    if (!log) c->host.logger = NULL;
    return c;
}

/* The native resource path (FMI 3.0: an absolute path ending in '/') as a folder without the
   trailing separators, on the heap; NULL with a message. */
static char *resource_folder(Component *c, fmi3String resourcePath)
{
    if (!resourcePath || !resourcePath[0]) {
        ds_logf(c, fmi2Error, "%s: resourcePath is %s: the FMU needs its resources folder",
                DS_FN_INSTANTIATE, resourcePath ? "empty" : "NULL");
        return NULL;
    }
    if (resourcePath[0] != '/') {
        ds_logf(c, fmi2Error, "%s: resourcePath '%s' is not an absolute path (FMI 3.0 passes the "
                "native path of the resources folder, not a URI)", DS_FN_INSTANTIATE,
                resourcePath);
        return NULL;
    }
    char *out = strdup(resourcePath);
    if (!out) {
        ds_logf(c, fmi2Error, "%s: out of memory", DS_FN_INSTANTIATE);
        return NULL;
    }
    for (size_t n = strlen(out); n > 1 && out[n - 1] == '/'; --n) out[n - 1] = '\0';
    return out;
}

EXPORT fmi3Instance fmi3InstantiateCoSimulation(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
    fmi3Boolean earlyReturnAllowed, const fmi3ValueReference requiredIntermediateVariables[],
    size_t nRequiredIntermediateVariables, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3IntermediateUpdateCallback intermediateUpdate)
{
    (void)earlyReturnAllowed, (void)requiredIntermediateVariables, (void)intermediateUpdate;
    Component *c = new_instance(instanceName, loggingOn, instanceEnvironment, logMessage);
    if (!c) return NULL;
    char *resources = NULL;
    if (!instanceName || !instanceName[0]) {
        ds_logf(c, fmi2Error, "%s: instanceName must be a non-empty string", DS_FN_INSTANTIATE);
        goto fail;
    }
    if (eventModeUsed) {
        ds_logf(c, fmi2Error, "%s: eventModeUsed is true, but %s.fmu has no event mode "
                "(hasEventMode is false)", DS_FN_INSTANTIATE, DS_MODEL_IDENTIFIER);
        goto fail;
    }
    if (nRequiredIntermediateVariables > 0) {
        ds_logf(c, fmi2Error, "%s: %zu required intermediate variables, but %s.fmu provides no "
                "intermediate update (providesIntermediateUpdate is false)", DS_FN_INSTANTIATE,
                nRequiredIntermediateVariables, DS_MODEL_IDENTIFIER);
        goto fail;
    }
    if (ds_check_token(c, instantiationToken) != 0) goto fail;
    if (!(resources = resource_folder(c, resourcePath))) goto fail;
    if (ds_start(c, resourcePath, resources, visible) != 0) goto fail;
    return c;
fail:
    free(resources);
    ds_destroy(c);
    return NULL;
}

/* The other interface types: NULL, with the message of why. */
static fmi3Instance refuse_interface(fmi3String instanceName, fmi3Boolean loggingOn,
                                     fmi3InstanceEnvironment environment,
                                     fmi3LogMessageCallback log, const char *fn, const char *what)
{
    Component *c = new_instance(instanceName, loggingOn, environment, log);
    if (!c) return NULL;
    ds_logf(c, fmi2Error, "%s: %s.fmu implements co-simulation only (not %s): call "
            "fmi3InstantiateCoSimulation", fn, DS_MODEL_IDENTIFIER, what);
    ds_destroy(c);
    return NULL;
}

EXPORT fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName,
                                                 fmi3String instantiationToken,
                                                 fmi3String resourcePath, fmi3Boolean visible,
                                                 fmi3Boolean loggingOn,
                                                 fmi3InstanceEnvironment instanceEnvironment,
                                                 fmi3LogMessageCallback logMessage)
{
    (void)instantiationToken, (void)resourcePath, (void)visible;
    return refuse_interface(instanceName, loggingOn, instanceEnvironment, logMessage,
                            "fmi3InstantiateModelExchange", "model exchange");
}

EXPORT fmi3Instance fmi3InstantiateScheduledExecution(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
    fmi3LockPreemptionCallback lockPreemption, fmi3UnlockPreemptionCallback unlockPreemption)
{
    (void)instantiationToken, (void)resourcePath, (void)visible, (void)clockUpdate;
    (void)lockPreemption, (void)unlockPreemption;
    return refuse_interface(instanceName, loggingOn, instanceEnvironment, logMessage,
                            "fmi3InstantiateScheduledExecution", "scheduled execution");
}

EXPORT void fmi3FreeInstance(fmi3Instance instance)
{
    Component *c = ds_component(instance);
    if (c) ds_free(c);
}

EXPORT fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn,
                                      size_t nCategories, const fmi3String categories[])
{
    Component *c = ds_component(instance);
    if (!ds_begin(c, "fmi3SetDebugLogging", MASK_SetDebugLogging)) return fmi3Error;
    return status3(ds_set_debug_logging(c, "fmi3SetDebugLogging", loggingOn, nCategories,
                                        categories));
}

/* ---- the life cycle -------------------------------------------------------------------------- */
EXPORT fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined,
                                              fmi3Float64 tolerance, fmi3Float64 startTime,
                                              fmi3Boolean stopTimeDefined, fmi3Float64 stopTime)
{
    Component *c = ds_component(instance);
    const char *fn = "fmi3EnterInitializationMode";
    if (!ds_begin(c, fn, MASK_EnterInitializationMode)) return fmi3Error;
    const fmi2Status s = ds_setup_experiment(c, fn, toleranceDefined, tolerance, startTime,
                                             stopTimeDefined, stopTime);
    if (s > fmi2Warning) return status3(s);
    const fmi2Status e = ds_enter_initialization(c);
    return status3(e > s ? e : s);
}

EXPORT fmi3Status fmi3ExitInitializationMode(fmi3Instance instance)
{
    Component *c = ds_component(instance);
    if (!ds_begin(c, "fmi3ExitInitializationMode", MASK_ExitInitializationMode)) return fmi3Error;
    return status3(ds_exit_initialization(c));
}

EXPORT fmi3Status fmi3Terminate(fmi3Instance instance)
{
    Component *c = ds_component(instance);
    if (!ds_begin(c, "fmi3Terminate", MASK_Terminate)) return fmi3Error;
    return status3(ds_terminate(c));
}

EXPORT fmi3Status fmi3Reset(fmi3Instance instance)
{
    Component *c = ds_component(instance);
    if (!ds_begin(c, "fmi3Reset", MASK_Reset)) return fmi3Error;
    return status3(ds_reset(c, "fmi3Reset"));
}

/* ---- values ---------------------------------------------------------------------------------- */
/* Every variable is a scalar: nValues must be nValueReferences. */
static int scalars(Component *c, const char *fn, size_t nvr, size_t nValues)
{
    if (nValues == nvr) return 1;
    ds_logf(c, fmi2Error, "%s: nValues = %zu for %zu value references: every variable of %s is a "
            "scalar (nValues must be %zu); nothing done", fn, nValues, nvr, DS_MODEL_IDENTIFIER,
            nvr);
    return 0;
}

/* Float64, Int32 and String: the same C types as FMI 2.0's Real, Integer and String. */
#define SAME_TYPE_SET(Name, CType, T)                                                              \
    EXPORT fmi3Status fmi3Set##Name(fmi3Instance instance, const fmi3ValueReference vr[],         \
                                    size_t nvr, const CType values[], size_t nValues)              \
    {                                                                                              \
        Component *c = ds_component(instance);                                                     \
        if (!ds_begin(c, "fmi3Set" #Name, MASK_Set)) return fmi3Error;                             \
        if (!scalars(c, "fmi3Set" #Name, nvr, nValues)) return fmi3Error;                          \
        if (!ds_check_vrs(c, "fmi3Set" #Name, vr, nvr, values, T, 1)) return fmi3Error;            \
        return status3(ds_set(c, vr, nvr, (const void *)values, T));                               \
    }
#define SAME_TYPE_GET(Name, CType, T)                                                              \
    EXPORT fmi3Status fmi3Get##Name(fmi3Instance instance, const fmi3ValueReference vr[],         \
                                    size_t nvr, CType values[], size_t nValues)                    \
    {                                                                                              \
        Component *c = ds_component(instance);                                                     \
        if (!ds_begin(c, "fmi3Get" #Name, MASK_Get)) return fmi3Error;                             \
        if (!scalars(c, "fmi3Get" #Name, nvr, nValues)) return fmi3Error;                          \
        if (!ds_check_vrs(c, "fmi3Get" #Name, vr, nvr, values, T, 0)) return fmi3Error;            \
        return status3(ds_get(c, vr, nvr, (void *)values, T));                                     \
    }
SAME_TYPE_SET(Float64, fmi3Float64, 'R')
SAME_TYPE_SET(Int32, fmi3Int32, 'I')
SAME_TYPE_SET(String, fmi3String, 'S')
SAME_TYPE_GET(Int32, fmi3Int32, 'I')
SAME_TYPE_GET(String, fmi3String, 'S')

/* Float64 values: the slave's, and the independent variable time (the instance's time: where
   the last step ended, or the start time), which only this layer knows. */
EXPORT fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                 fmi3Float64 values[], size_t nValues)
{
    Component *c = ds_component(instance);
    const char *fn = "fmi3GetFloat64";
    if (!ds_begin(c, fn, MASK_Get) || !scalars(c, fn, nvr, nValues)) return fmi3Error;
    if (!ds_check_vrs(c, fn, vr, nvr, values, 'R', 0)) return fmi3Error;
    size_t times = 0;
    for (size_t i = 0; i < nvr; ++i) times += DS_VARIABLES[vr[i]].causality == DS_INDEPENDENT;
    if (times == 0) return status3(ds_get(c, vr, nvr, values, 'R'));
    fmi2Status worst = fmi2OK;
    for (size_t i = 0; i < nvr && worst <= fmi2Warning; ++i) {
        if (DS_VARIABLES[vr[i]].causality == DS_INDEPENDENT) {
            values[i] = c->last_time;
        } else {
            const fmi2Status s = ds_get(c, &vr[i], 1, &values[i], 'R');
            if (s > worst) worst = s;
        }
    }
    return status3(worst);
}

/* A buffer of nvr FMI 2.0 integers (Booleans, enumerations), or NULL (logged). */
static fmi2Integer *integers(Component *c, const char *fn, size_t nvr)
{
    fmi2Integer *out = calloc(nvr ? nvr : 1, sizeof *out);
    if (!out) ds_logf(c, fmi2Error, "%s: out of memory", fn);
    return out;
}

EXPORT fmi3Status fmi3GetBoolean(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                 fmi3Boolean values[], size_t nValues)
{
    Component *c = ds_component(instance);
    const char *fn = "fmi3GetBoolean";
    if (!ds_begin(c, fn, MASK_Get) || !scalars(c, fn, nvr, nValues)) return fmi3Error;
    if (!ds_check_vrs(c, fn, vr, nvr, values, 'B', 0)) return fmi3Error;
    fmi2Integer *b = integers(c, fn, nvr);
    if (!b) return fmi3Error;
    const fmi2Status s = ds_get(c, vr, nvr, b, 'B');
    if (s <= fmi2Warning)
        for (size_t i = 0; i < nvr; ++i) values[i] = b[i] != fmi2False;
    free(b);
    return status3(s);
}

EXPORT fmi3Status fmi3SetBoolean(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                 const fmi3Boolean values[], size_t nValues)
{
    Component *c = ds_component(instance);
    const char *fn = "fmi3SetBoolean";
    if (!ds_begin(c, fn, MASK_Set) || !scalars(c, fn, nvr, nValues)) return fmi3Error;
    if (nvr > 0 && !values) {
        ds_check_vrs(c, fn, vr, nvr, values, 'B', 1); /* names what is NULL */
        return fmi3Error;
    }
    fmi2Integer *b = integers(c, fn, nvr);
    if (!b) return fmi3Error;
    /* the byte as the host wrote it: a bool that is neither 0 nor 1 is refused (ds_check_vrs) */
    for (size_t i = 0; i < nvr; ++i) b[i] = ((const unsigned char *)values)[i];
    fmi2Status s = fmi2Error;
    if (ds_check_vrs(c, fn, vr, nvr, b, 'B', 1)) s = ds_set(c, vr, nvr, b, 'B');
    free(b);
    return status3(s);
}

/* Enumerations are Int64 in FMI 3.0; the slave's are FMI 2.0 integers. */
EXPORT fmi3Status fmi3GetInt64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                               fmi3Int64 values[], size_t nValues)
{
    Component *c = ds_component(instance);
    const char *fn = "fmi3GetInt64";
    if (!ds_begin(c, fn, MASK_Get) || !scalars(c, fn, nvr, nValues)) return fmi3Error;
    if (!ds_check_vrs(c, fn, vr, nvr, values, 'E', 0)) return fmi3Error;
    fmi2Integer *e = integers(c, fn, nvr);
    if (!e) return fmi3Error;
    const fmi2Status s = ds_get(c, vr, nvr, e, 'I');
    if (s <= fmi2Warning)
        for (size_t i = 0; i < nvr; ++i) values[i] = e[i];
    free(e);
    return status3(s);
}

EXPORT fmi3Status fmi3SetInt64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                               const fmi3Int64 values[], size_t nValues)
{
    Component *c = ds_component(instance);
    const char *fn = "fmi3SetInt64";
    if (!ds_begin(c, fn, MASK_Set) || !scalars(c, fn, nvr, nValues)) return fmi3Error;
    if (!ds_check_vrs(c, fn, vr, nvr, values, 'E', 1)) return fmi3Error;
    for (size_t i = 0; i < nvr; ++i) {
        if (values[i] < INT32_MIN || values[i] > INT32_MAX) {
            ds_logf(c, fmi2Error, "%s: value %lld for %s is not an item of its enumeration; "
                    "nothing done", fn, (long long)values[i], DS_VARIABLES[vr[i]].name);
            return fmi3Error;
        }
    }
    fmi2Integer *e = integers(c, fn, nvr);
    if (!e) return fmi3Error;
    for (size_t i = 0; i < nvr; ++i) e[i] = (fmi2Integer)values[i];
    const fmi2Status s = ds_set(c, vr, nvr, e, 'I');
    free(e);
    return status3(s);
}

/* The types this FMU has no variables of: fmi3Error, with the message that says so. */
static fmi3Status no_such_type(fmi3Instance instance, const char *fn, int mask, const char *type,
                               const fmi3ValueReference vr[], size_t nvr)
{
    Component *c = ds_component(instance);
    if (!ds_begin(c, fn, mask)) return fmi3Error;
    if (nvr == 0) return fmi3OK;
    if (!vr) {
        ds_logf(c, fmi2Error, "%s: valueReferences is NULL for nValueReferences = %zu", fn, nvr);
        return fmi3Error;
    }
    const ds_variable *v = vr[0] < DS_N_VR ? &DS_VARIABLES[vr[0]] : NULL;
    if (v && v->name)
        ds_logf(c, fmi2Error, "%s: %s.fmu has no %s variables: %s (value reference %u) is not one; "
                "nothing done", fn, DS_MODEL_IDENTIFIER, type, v->name, vr[0]);
    else
        ds_logf(c, fmi2Error, "%s: no variable has value reference %u (valueReferences[0]); "
                "nothing done", fn, vr[0]);
    return fmi3Error;
}

#define OTHER_TYPE(Name, CType)                                                                    \
    EXPORT fmi3Status fmi3Get##Name(fmi3Instance instance, const fmi3ValueReference vr[],         \
                                    size_t nvr, CType values[], size_t nValues)                    \
    {                                                                                              \
        (void)values, (void)nValues;                                                               \
        return no_such_type(instance, "fmi3Get" #Name, MASK_Get, #Name, vr, nvr);                  \
    }                                                                                              \
    EXPORT fmi3Status fmi3Set##Name(fmi3Instance instance, const fmi3ValueReference vr[],         \
                                    size_t nvr, const CType values[], size_t nValues)              \
    {                                                                                              \
        (void)values, (void)nValues;                                                               \
        return no_such_type(instance, "fmi3Set" #Name, MASK_Set, #Name, vr, nvr);                  \
    }
OTHER_TYPE(Float32, fmi3Float32)
OTHER_TYPE(Int8, fmi3Int8)
OTHER_TYPE(UInt8, fmi3UInt8)
OTHER_TYPE(Int16, fmi3Int16)
OTHER_TYPE(UInt16, fmi3UInt16)
OTHER_TYPE(UInt32, fmi3UInt32)
OTHER_TYPE(UInt64, fmi3UInt64)

EXPORT fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                size_t valueSizes[], fmi3Binary values[], size_t nValues)
{
    (void)valueSizes, (void)values, (void)nValues;
    return no_such_type(instance, "fmi3GetBinary", MASK_Get, "Binary", vr, nvr);
}

EXPORT fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                const size_t valueSizes[], const fmi3Binary values[],
                                size_t nValues)
{
    (void)valueSizes, (void)values, (void)nValues;
    return no_such_type(instance, "fmi3SetBinary", MASK_Set, "Binary", vr, nvr);
}

EXPORT fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                               fmi3Clock values[])
{
    (void)values;
    return no_such_type(instance, "fmi3GetClock", MASK_Get, "Clock", vr, nvr);
}

EXPORT fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                               const fmi3Clock values[])
{
    (void)values;
    return no_such_type(instance, "fmi3SetClock", MASK_Set, "Clock", vr, nvr);
}

/* ---- stepping -------------------------------------------------------------------------------- */
EXPORT fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                             fmi3Float64 communicationStepSize,
                             fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                             fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                             fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime)
{
    Component *c = ds_component(instance);
    if (!ds_begin(c, "fmi3DoStep", MASK_DoStep)) return fmi3Error;
    if (!eventHandlingNeeded || !terminateSimulation || !earlyReturn || !lastSuccessfulTime) {
        ds_logf(c, fmi2Error, "fmi3DoStep: %s is NULL; nothing was computed",
                !eventHandlingNeeded ? "eventHandlingNeeded" : !terminateSimulation
                ? "terminateSimulation" : !earlyReturn ? "earlyReturn" : "lastSuccessfulTime");
        return fmi3Error;
    }
    const fmi2Status s = ds_do_step(c, "fmi3DoStep", currentCommunicationPoint,
                                    communicationStepSize, noSetFMUStatePriorToCurrentPoint);
    *eventHandlingNeeded = false; /* no events: hasEventMode is false */
    /* never: after a discard the master may restore an earlier state (fmi3SetFMUState) */
    *terminateSimulation = false;
    *earlyReturn = false; /* a step ends where it was asked to, or is discarded */
    *lastSuccessfulTime = c->last_time;
    return status3(s);
}

/* ---- FMU states (states.c) ------------------------------------------------------------------- */
EXPORT fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState)
{
    Component *c = ds_component(instance);
    if (!ds_begin(c, "fmi3GetFMUState", MASK_FMUState)) return fmi3Error;
    return status3(ds_state_get(c, FMUState));
}

EXPORT fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState)
{
    Component *c = ds_component(instance);
    if (!ds_begin(c, "fmi3SetFMUState", MASK_FMUState)) return fmi3Error;
    return status3(ds_state_set(c, FMUState));
}

EXPORT fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState)
{
    Component *c = ds_component(instance);
    if (!ds_begin(c, "fmi3FreeFMUState", MASK_FMUState)) return fmi3Error;
    return status3(ds_state_free(c, FMUState));
}

EXPORT fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState,
                                             size_t *size)
{
    Component *c = ds_component(instance);
    if (!ds_begin(c, "fmi3SerializedFMUStateSize", MASK_FMUState)) return fmi3Error;
    return status3(ds_state_size(c, FMUState, size));
}

EXPORT fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState,
                                        fmi3Byte serializedState[], size_t size)
{
    Component *c = ds_component(instance);
    if (!ds_begin(c, "fmi3SerializeFMUState", MASK_FMUState)) return fmi3Error;
    return status3(ds_state_serialize(c, FMUState, (fmi2Byte *)serializedState, size));
}

EXPORT fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[],
                                          size_t size, fmi3FMUState *FMUState)
{
    Component *c = ds_component(instance);
    if (!ds_begin(c, "fmi3DeserializeFMUState", MASK_FMUState)) return fmi3Error;
    return status3(ds_state_deserialize(c, (const fmi2Byte *)serializedState, size, FMUState));
}

/* ---- what the FMU does not provide ----------------------------------------------------------- */
/* fmi3Error with "<fn>: not provided (<why>)" (after the usual check of the instance). */
static fmi3Status not_provided(fmi3Instance instance, const char *fn, const char *why)
{
    Component *c = ds_component(instance);
    if (!ds_begin(c, fn, ST_ANY_LIVE)) return fmi3Error;
    ds_logf(c, fmi2Error, "%s: not provided (%s)", fn, why);
    return fmi3Error;
}

/* The parameters after Params: ", (void)p" for each unused parameter p but the instance. */
#define NOT_PROVIDED(Name, Why, Params, ...)                                                      \
    EXPORT fmi3Status fmi3##Name Params                                                           \
    {                                                                                              \
        (void)instance __VA_ARGS__;                                                                \
        return not_provided(instance, "fmi3" #Name, Why);                                          \
    }
#define NO_EVENTS "hasEventMode is false"
#define NO_CLOCKS "the FMU has no clocks"
#define NO_ME "the FMU implements co-simulation only"

NOT_PROVIDED(EnterEventMode, NO_EVENTS, (fmi3Instance instance), )
NOT_PROVIDED(EnterStepMode, NO_EVENTS, (fmi3Instance instance), )
NOT_PROVIDED(EvaluateDiscreteStates, NO_EVENTS, (fmi3Instance instance), )
NOT_PROVIDED(UpdateDiscreteStates, NO_EVENTS,
             (fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
              fmi3Boolean *terminateSimulation, fmi3Boolean *nominalsOfContinuousStatesChanged,
              fmi3Boolean *valuesOfContinuousStatesChanged, fmi3Boolean *nextEventTimeDefined,
              fmi3Float64 *nextEventTime),
             , (void)discreteStatesNeedUpdate, (void)terminateSimulation,
             (void)nominalsOfContinuousStatesChanged, (void)valuesOfContinuousStatesChanged,
             (void)nextEventTimeDefined, (void)nextEventTime)
NOT_PROVIDED(EnterConfigurationMode, "the FMU has no structural parameters",
             (fmi3Instance instance), )
NOT_PROVIDED(ExitConfigurationMode, "the FMU has no structural parameters",
             (fmi3Instance instance), )
NOT_PROVIDED(GetNumberOfVariableDependencies, "providesPerElementDependencies is false",
             (fmi3Instance instance, fmi3ValueReference valueReference, size_t *nDependencies),
             , (void)valueReference, (void)nDependencies)
NOT_PROVIDED(GetVariableDependencies, "providesPerElementDependencies is false",
             (fmi3Instance instance, fmi3ValueReference dependent,
              size_t elementIndicesOfDependent[], fmi3ValueReference independents[],
              size_t elementIndicesOfIndependents[], fmi3DependencyKind dependencyKinds[],
              size_t nDependencies),
             , (void)dependent, (void)elementIndicesOfDependent, (void)independents,
             (void)elementIndicesOfIndependents, (void)dependencyKinds, (void)nDependencies)
NOT_PROVIDED(GetDirectionalDerivative, "providesDirectionalDerivative is false",
             (fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
              const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
              size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity),
             , (void)unknowns, (void)nUnknowns, (void)knowns, (void)nKnowns, (void)seed,
             (void)nSeed, (void)sensitivity, (void)nSensitivity)
NOT_PROVIDED(GetAdjointDerivative, "providesAdjointDerivatives is false",
             (fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
              const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
              size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity),
             , (void)unknowns, (void)nUnknowns, (void)knowns, (void)nKnowns, (void)seed,
             (void)nSeed, (void)sensitivity, (void)nSensitivity)
NOT_PROVIDED(GetOutputDerivatives, "maxOutputDerivativeOrder is 0",
             (fmi3Instance instance, const fmi3ValueReference valueReferences[],
              size_t nValueReferences, const fmi3Int32 orders[], fmi3Float64 values[],
              size_t nValues),
             , (void)valueReferences, (void)nValueReferences, (void)orders, (void)values,
             (void)nValues)
NOT_PROVIDED(GetIntervalDecimal, NO_CLOCKS,
             (fmi3Instance instance, const fmi3ValueReference valueReferences[],
              size_t nValueReferences, fmi3Float64 intervals[],
              fmi3IntervalQualifier qualifiers[]),
             , (void)valueReferences, (void)nValueReferences, (void)intervals, (void)qualifiers)
NOT_PROVIDED(GetIntervalFraction, NO_CLOCKS,
             (fmi3Instance instance, const fmi3ValueReference valueReferences[],
              size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[],
              fmi3IntervalQualifier qualifiers[]),
             , (void)valueReferences, (void)nValueReferences, (void)counters, (void)resolutions,
             (void)qualifiers)
NOT_PROVIDED(GetShiftDecimal, NO_CLOCKS,
             (fmi3Instance instance, const fmi3ValueReference valueReferences[],
              size_t nValueReferences, fmi3Float64 shifts[]),
             , (void)valueReferences, (void)nValueReferences, (void)shifts)
NOT_PROVIDED(GetShiftFraction, NO_CLOCKS,
             (fmi3Instance instance, const fmi3ValueReference valueReferences[],
              size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[]),
             , (void)valueReferences, (void)nValueReferences, (void)counters, (void)resolutions)
NOT_PROVIDED(SetIntervalDecimal, NO_CLOCKS,
             (fmi3Instance instance, const fmi3ValueReference valueReferences[],
              size_t nValueReferences, const fmi3Float64 intervals[]),
             , (void)valueReferences, (void)nValueReferences, (void)intervals)
NOT_PROVIDED(SetIntervalFraction, NO_CLOCKS,
             (fmi3Instance instance, const fmi3ValueReference valueReferences[],
              size_t nValueReferences, const fmi3UInt64 counters[],
              const fmi3UInt64 resolutions[]),
             , (void)valueReferences, (void)nValueReferences, (void)counters, (void)resolutions)
NOT_PROVIDED(SetShiftDecimal, NO_CLOCKS,
             (fmi3Instance instance, const fmi3ValueReference valueReferences[],
              size_t nValueReferences, const fmi3Float64 shifts[]),
             , (void)valueReferences, (void)nValueReferences, (void)shifts)
NOT_PROVIDED(SetShiftFraction, NO_CLOCKS,
             (fmi3Instance instance, const fmi3ValueReference valueReferences[],
              size_t nValueReferences, const fmi3UInt64 counters[],
              const fmi3UInt64 resolutions[]),
             , (void)valueReferences, (void)nValueReferences, (void)counters, (void)resolutions)
NOT_PROVIDED(ActivateModelPartition, "the FMU implements co-simulation only",
             (fmi3Instance instance, fmi3ValueReference clockReference,
              fmi3Float64 activationTime),
             , (void)clockReference, (void)activationTime)
NOT_PROVIDED(EnterContinuousTimeMode, NO_ME, (fmi3Instance instance), )
NOT_PROVIDED(CompletedIntegratorStep, NO_ME,
             (fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
              fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation),
             , (void)noSetFMUStatePriorToCurrentPoint, (void)enterEventMode,
             (void)terminateSimulation)
NOT_PROVIDED(SetTime, NO_ME, (fmi3Instance instance, fmi3Float64 time), , (void)time)
NOT_PROVIDED(SetContinuousStates, NO_ME,
             (fmi3Instance instance, const fmi3Float64 continuousStates[],
              size_t nContinuousStates),
             , (void)continuousStates, (void)nContinuousStates)
NOT_PROVIDED(GetContinuousStateDerivatives, NO_ME,
             (fmi3Instance instance, fmi3Float64 derivatives[], size_t nContinuousStates),
             , (void)derivatives, (void)nContinuousStates)
NOT_PROVIDED(GetEventIndicators, NO_ME,
             (fmi3Instance instance, fmi3Float64 eventIndicators[], size_t nEventIndicators),
             , (void)eventIndicators, (void)nEventIndicators)
NOT_PROVIDED(GetContinuousStates, NO_ME,
             (fmi3Instance instance, fmi3Float64 continuousStates[], size_t nContinuousStates),
             , (void)continuousStates, (void)nContinuousStates)
NOT_PROVIDED(GetNominalsOfContinuousStates, NO_ME,
             (fmi3Instance instance, fmi3Float64 nominals[], size_t nContinuousStates),
             , (void)nominals, (void)nContinuousStates)
NOT_PROVIDED(GetNumberOfEventIndicators, NO_ME,
             (fmi3Instance instance, size_t *nEventIndicators), , (void)nEventIndicators)
NOT_PROVIDED(GetNumberOfContinuousStates, NO_ME,
             (fmi3Instance instance, size_t *nContinuousStates), , (void)nContinuousStates)
