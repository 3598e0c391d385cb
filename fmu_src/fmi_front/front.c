/*
 * front.c -- the FMI 2.0 functions of the drillstring FMUs (drillstring_fmi2.h).
 *
 * Each function checks the call against the co-simulation state machine of FMI 2.0, section
 * 4.2.4 (a mask of the states in which the standard allows the call) and what only FMI 2.0 has
 * (fmuType, the status functions), and hands the rest to machine.c, which the FMI 3.0 front
 * (front3.c) shares.
 */
#include "drillstring_fmi2.h"

#include <stdlib.h>

#define MASK_SetDebugLogging ST_ANY_LIVE
#define MASK_SetupExperiment ST_INSTANTIATED
#define MASK_EnterInitializationMode ST_INSTANTIATED
#define MASK_ExitInitializationMode ST_INITIALIZATION
#define MASK_Terminate (ST_STEP_COMPLETE | ST_STEP_FAILED)
#define MASK_Reset ST_ANY_LIVE
#define MASK_Get (ST_INITIALIZATION | ST_STEP_COMPLETE | ST_STEP_FAILED | ST_TERMINATED)
#define MASK_Set (ST_INSTANTIATED | ST_INITIALIZATION | ST_STEP_COMPLETE)
#define MASK_FMUstate ST_ANY_LIVE
#define MASK_DirectionalDerivative MASK_Get
#define MASK_SetRealInputDerivatives (ST_INSTANTIATED | ST_INITIALIZATION | ST_STEP_COMPLETE)
#define MASK_GetRealOutputDerivatives (ST_STEP_COMPLETE | ST_STEP_FAILED | ST_TERMINATED)
#define MASK_DoStep ST_STEP_COMPLETE
#define MASK_CancelStep 0 /* StepInProgress: fmi2DoStep never returns fmi2Pending */
#define MASK_Status (ST_STEP_COMPLETE | ST_STEP_FAILED | ST_TERMINATED)

/* ---- FMI functions: instantiation ------------------------------------------------------------ */
EXPORT const char *fmi2GetTypesPlatform(void) { return "default"; }
EXPORT const char *fmi2GetVersion(void) { return "2.0"; }

EXPORT fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                                     fmi2String fmuResourceLocation,
                                     const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                                     fmi2Boolean loggingOn)
{
    if (!functions) return NULL; /* nowhere to say why */
    Component *c = ds_new_component(instanceName, loggingOn != fmi2False);
    if (!c) return NULL;
    c->host = *functions;
    char *err = malloc(ERR_LEN), *resources = NULL; /* on the heap: hosts' threads may have small
                                                        stacks */
    if (!err) {
        ds_logf(c, fmi2Error, "fmi2Instantiate: out of memory");
        goto fail;
    }
    if (!instanceName || !instanceName[0]) {
        ds_logf(c, fmi2Error, "fmi2Instantiate: instanceName must be a non-empty string");
        goto fail;
    }
    if (fmuType != fmi2CoSimulation) {
        ds_logf(c, fmi2Error, "fmi2Instantiate: fmuType %s (%d): %s.fmu implements co-simulation "
                "only (fmi2CoSimulation)", fmuType == fmi2ModelExchange ? "fmi2ModelExchange" :
                "unknown", (int)fmuType, DS_MODEL_IDENTIFIER);
        goto fail;
    }
    if (ds_check_token(c, fmuGUID) != 0) goto fail;
    if (!(resources = ds_uri_to_path(fmuResourceLocation, err, ERR_LEN))) {
        ds_logf(c, fmi2Error, "fmi2Instantiate: %s", err);
        goto fail;
    }
    if (ds_start(c, fmuResourceLocation, resources, visible) != 0) goto fail;
    free(err);
    return c;
fail:
    free(resources);
    free(err);
    ds_destroy(c);
    return NULL;
}

EXPORT void fmi2FreeInstance(fmi2Component comp)
{
    Component *c = ds_component(comp);
    if (c) ds_free(c);
}

EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component comp, fmi2Boolean loggingOn,
                                      size_t nCategories, const fmi2String categories[])
{
    Component *c = ds_component(comp);
    if (!ds_begin(c, "fmi2SetDebugLogging", MASK_SetDebugLogging)) return fmi2Error;
    return ds_set_debug_logging(c, "fmi2SetDebugLogging", loggingOn != fmi2False, nCategories,
                                categories);
}

/* ---- FMI functions: the life cycle ----------------------------------------------------------- */
EXPORT fmi2Status fmi2SetupExperiment(fmi2Component comp, fmi2Boolean toleranceDefined,
                                      fmi2Real tolerance, fmi2Real startTime,
                                      fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    Component *c = ds_component(comp);
    if (!ds_begin(c, "fmi2SetupExperiment", MASK_SetupExperiment)) return fmi2Error;
    return ds_setup_experiment(c, "fmi2SetupExperiment", toleranceDefined, tolerance, startTime,
                               stopTimeDefined, stopTime);
}

EXPORT fmi2Status fmi2EnterInitializationMode(fmi2Component comp)
{
    Component *c = ds_component(comp);
    if (!ds_begin(c, "fmi2EnterInitializationMode", MASK_EnterInitializationMode)) return fmi2Error;
    return ds_enter_initialization(c);
}

EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component comp)
{
    Component *c = ds_component(comp);
    if (!ds_begin(c, "fmi2ExitInitializationMode", MASK_ExitInitializationMode)) return fmi2Error;
    return ds_exit_initialization(c);
}

EXPORT fmi2Status fmi2Terminate(fmi2Component comp)
{
    Component *c = ds_component(comp);
    if (!ds_begin(c, "fmi2Terminate", MASK_Terminate)) return fmi2Error;
    return ds_terminate(c);
}

EXPORT fmi2Status fmi2Reset(fmi2Component comp)
{
    Component *c = ds_component(comp);
    if (!ds_begin(c, "fmi2Reset", MASK_Reset)) return fmi2Error;
    return ds_reset(c, "fmi2Reset");
}

/* ---- FMI functions: values ------------------------------------------------------------------- */
#define GETTER(Name, CType, T)                                                                     \
    EXPORT fmi2Status fmi2Get##Name(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, \
                                    CType value[])                                                 \
    {                                                                                              \
        Component *c = ds_component(comp);                                                            \
        if (!ds_begin(c, "fmi2Get" #Name, MASK_Get)) return fmi2Error;                                \
        if (!ds_check_vrs(c, "fmi2Get" #Name, vr, nvr, value, T, 0)) return fmi2Error;             \
        return ds_get(c, vr, nvr, (void *)value, T);                                               \
    }
#define SETTER(Name, CType, T)                                                                     \
    EXPORT fmi2Status fmi2Set##Name(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, \
                                    const CType value[])                                           \
    {                                                                                              \
        Component *c = ds_component(comp);                                                            \
        if (!ds_begin(c, "fmi2Set" #Name, MASK_Set)) return fmi2Error;                                \
        if (!ds_check_vrs(c, "fmi2Set" #Name, vr, nvr, value, T, 1)) return fmi2Error;             \
        return ds_set(c, vr, nvr, (const void *)value, T);                                         \
    }
GETTER(Real, fmi2Real, 'R')
GETTER(Integer, fmi2Integer, 'I')
GETTER(Boolean, fmi2Boolean, 'B')
GETTER(String, fmi2String, 'S')
SETTER(Real, fmi2Real, 'R')
SETTER(Integer, fmi2Integer, 'I')
SETTER(Boolean, fmi2Boolean, 'B')
SETTER(String, fmi2String, 'S')

/* ---- FMI functions: stepping and status ------------------------------------------------------ */
EXPORT fmi2Status fmi2DoStep(fmi2Component comp, fmi2Real currentCommunicationPoint,
                             fmi2Real communicationStepSize,
                             fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    Component *c = ds_component(comp);
    if (!ds_begin(c, "fmi2DoStep", MASK_DoStep)) return fmi2Error;
    return ds_do_step(c, "fmi2DoStep", currentCommunicationPoint, communicationStepSize,
                      noSetFMUStatePriorToCurrentPoint);
}

EXPORT fmi2Status fmi2CancelStep(fmi2Component comp)
{
    Component *c = ds_component(comp);
    ds_begin(c, "fmi2CancelStep", MASK_CancelStep);
    return fmi2Error;
}

EXPORT fmi2Status fmi2GetStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Status *value)
{
    Component *c = ds_component(comp);
    if (!ds_begin(c, "fmi2GetStatus", MASK_Status)) return fmi2Error;
    (void)value;
    ds_logf(c, fmi2Discard, "fmi2GetStatus(%d): not available: fmi2DoStep never returns "
            "fmi2Pending", (int)s);
    return fmi2Discard;
}

EXPORT fmi2Status fmi2GetRealStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Real *value)
{
    Component *c = ds_component(comp);
    if (!ds_begin(c, "fmi2GetRealStatus", MASK_Status)) return fmi2Error;
    if (s != fmi2LastSuccessfulTime) {
        ds_logf(c, fmi2Discard, "fmi2GetRealStatus(%d): only fmi2LastSuccessfulTime is available",
                (int)s);
        return fmi2Discard;
    }
    if (!value) {
        ds_logf(c, fmi2Error, "fmi2GetRealStatus: value is NULL");
        return fmi2Error;
    }
    *value = c->last_time;
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetIntegerStatus(fmi2Component comp, const fmi2StatusKind s,
                                       fmi2Integer *value)
{
    Component *c = ds_component(comp);
    if (!ds_begin(c, "fmi2GetIntegerStatus", MASK_Status)) return fmi2Error;
    (void)value;
    ds_logf(c, fmi2Discard, "fmi2GetIntegerStatus(%d): no integer status is available", (int)s);
    return fmi2Discard;
}

EXPORT fmi2Status fmi2GetBooleanStatus(fmi2Component comp, const fmi2StatusKind s,
                                       fmi2Boolean *value)
{
    Component *c = ds_component(comp);
    if (!ds_begin(c, "fmi2GetBooleanStatus", MASK_Status)) return fmi2Error;
    if (s != fmi2Terminated) {
        ds_logf(c, fmi2Discard, "fmi2GetBooleanStatus(%d): only fmi2Terminated is available",
                (int)s);
        return fmi2Discard;
    }
    if (!value) {
        ds_logf(c, fmi2Error, "fmi2GetBooleanStatus: value is NULL");
        return fmi2Error;
    }
    /* never: after a discard the master may restore an earlier state (fmi2SetFMUstate) */
    *value = fmi2False;
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetStringStatus(fmi2Component comp, const fmi2StatusKind s,
                                      fmi2String *value)
{
    Component *c = ds_component(comp);
    if (!ds_begin(c, "fmi2GetStringStatus", MASK_Status)) return fmi2Error;
    (void)value;
    ds_logf(c, fmi2Discard, "fmi2GetStringStatus(%d): not available: fmi2DoStep never returns "
            "fmi2Pending", (int)s);
    return fmi2Discard;
}

EXPORT fmi2Status fmi2GetDirectionalDerivative(fmi2Component comp, const fmi2ValueReference u[],
                                               size_t nu, const fmi2ValueReference z[], size_t nz,
                                               const fmi2Real dv[], fmi2Real dz[])
{
    Component *c = ds_component(comp);
    (void)u, (void)nu, (void)z, (void)nz, (void)dv, (void)dz;
    if (!ds_begin(c, "fmi2GetDirectionalDerivative", MASK_DirectionalDerivative)) return fmi2Error;
    ds_logf(c, fmi2Error, "fmi2GetDirectionalDerivative: not provided "
            "(providesDirectionalDerivative is false)");
    return fmi2Error;
}

EXPORT fmi2Status fmi2SetRealInputDerivatives(fmi2Component comp, const fmi2ValueReference vr[],
                                              size_t nvr, const fmi2Integer order[],
                                              const fmi2Real value[])
{
    Component *c = ds_component(comp);
    (void)vr, (void)nvr, (void)order, (void)value;
    if (!ds_begin(c, "fmi2SetRealInputDerivatives", MASK_SetRealInputDerivatives)) return fmi2Error;
    ds_logf(c, fmi2Error, "fmi2SetRealInputDerivatives: not provided (canInterpolateInputs is "
            "false): inputs are held constant over each step");
    return fmi2Error;
}

EXPORT fmi2Status fmi2GetRealOutputDerivatives(fmi2Component comp, const fmi2ValueReference vr[],
                                               size_t nvr, const fmi2Integer order[],
                                               fmi2Real value[])
{
    Component *c = ds_component(comp);
    (void)vr, (void)nvr, (void)order, (void)value;
    if (!ds_begin(c, "fmi2GetRealOutputDerivatives", MASK_GetRealOutputDerivatives))
        return fmi2Error;
    ds_logf(c, fmi2Error, "fmi2GetRealOutputDerivatives: not provided "
            "(maxOutputDerivativeOrder is 0)");
    return fmi2Error;
}


/* ---- FMI functions: FMU states (states.c) ---------------------------------------------------- */
EXPORT fmi2Status fmi2GetFMUstate(fmi2Component comp, fmi2FMUstate *FMUstate)
{
    Component *c = ds_component(comp);
    if (!ds_begin(c, "fmi2GetFMUstate", MASK_FMUstate)) return fmi2Error;
    return ds_state_get(c, FMUstate);
}

EXPORT fmi2Status fmi2SetFMUstate(fmi2Component comp, fmi2FMUstate FMUstate)
{
    Component *c = ds_component(comp);
    if (!ds_begin(c, "fmi2SetFMUstate", MASK_FMUstate)) return fmi2Error;
    return ds_state_set(c, FMUstate);
}

EXPORT fmi2Status fmi2FreeFMUstate(fmi2Component comp, fmi2FMUstate *FMUstate)
{
    Component *c = ds_component(comp);
    if (!ds_begin(c, "fmi2FreeFMUstate", MASK_FMUstate)) return fmi2Error;
    return ds_state_free(c, FMUstate);
}

EXPORT fmi2Status fmi2SerializedFMUstateSize(fmi2Component comp, fmi2FMUstate FMUstate,
                                             size_t *size)
{
    Component *c = ds_component(comp);
    if (!ds_begin(c, "fmi2SerializedFMUstateSize", MASK_FMUstate)) return fmi2Error;
    return ds_state_size(c, FMUstate, size);
}

EXPORT fmi2Status fmi2SerializeFMUstate(fmi2Component comp, fmi2FMUstate FMUstate,
                                        fmi2Byte serializedState[], size_t size)
{
    Component *c = ds_component(comp);
    if (!ds_begin(c, "fmi2SerializeFMUstate", MASK_FMUstate)) return fmi2Error;
    return ds_state_serialize(c, FMUstate, serializedState, size);
}

EXPORT fmi2Status fmi2DeSerializeFMUstate(fmi2Component comp, const fmi2Byte serializedState[],
                                          size_t size, fmi2FMUstate *FMUstate)
{
    Component *c = ds_component(comp);
    if (!ds_begin(c, "fmi2DeSerializeFMUstate", MASK_FMUstate)) return fmi2Error;
    return ds_state_deserialize(c, serializedState, size, FMUstate);
}
