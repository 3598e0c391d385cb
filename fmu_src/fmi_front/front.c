/*
 * front.c -- the FMI 2.0 functions of the drillstring FMUs (drillstring_fmi2.h).
 *
 * Every function first checks the call against the co-simulation state machine of FMI 2.0,
 * section 4.2.4 (in the style of the Modelica Association's Reference FMUs: a mask of the states
 * in which the standard allows the call; otherwise fmi2Error with "illegal call sequence"), then
 * what is structural (GUID, fmuType, value references, types, causality and variability against
 * the state), before anything reaches Python. What passes goes to the native fast path (fast.c)
 * or to pythonfmu's library. The Python slave reports problems as log messages (it never raises
 * into pythonfmu); the layer returns the worst status logged in the call, so a rejected value is
 * fmi2Error from the very call that received it, the value not applied.
 */
#define DS_MODEL_TABLES /* DS_VARIABLES and DS_LOG_CATEGORIES are defined here */
#include "drillstring_fmi2.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

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

const char *ds_state_name(int s)
{
    switch (s) {
    case ST_INSTANTIATED: return "Instantiated";
    case ST_INITIALIZATION: return "InitializationMode";
    case ST_STEP_COMPLETE: return "StepComplete";
    case ST_STEP_FAILED: return "StepFailed (after fmi2Discard)";
    case ST_TERMINATED: return "Terminated";
    case ST_FATAL: return "Fatal";
    default: return "?";
    }
}

/* ---- call checks ----------------------------------------------------------------------------- */
static Component *component(fmi2Component comp)
{
    Component *c = comp;
    return (c && c->magic == COMPONENT_MAGIC) ? c : NULL;
}

/* A list item appended to out[cap] (cut visibly with "..." if it does not fit). */
static void append_item(char *out, size_t cap, const char *item)
{
    const size_t len = strlen(out);
    if (len + 1 < cap) ds_format(out + len, cap - len, "%s%s", len ? ", " : "", item);
}

static void allowed_states(int mask, char *out, size_t n)
{
    out[0] = '\0';
    for (int s = ST_INSTANTIATED; s <= ST_FATAL; s <<= 1)
        if (mask & s) append_item(out, n, ds_state_name(s));
    if (!out[0]) ds_format(out, n, "StepInProgress, which this FMU never enters");
}

/* Start a call: known instance, allowed state (else "illegal call sequence"). */
static int begin(Component *c, const char *fn, int mask)
{
    if (!c) return 0;
    c->call_status = fmi2OK;
    if (!(c->state & mask)) {
        char allowed[256];
        allowed_states(mask, allowed, sizeof allowed);
        ds_logf(c, fmi2Error, "%s: illegal call sequence: not allowed in state %s (allowed in: %s)",
                fn, ds_state_name(c->state), allowed);
        return 0;
    }
    return 1;
}

/* The status of a forwarded call: the worse of pythonfmu's and the worst logged. */
fmi2Status ds_finish(Component *c, fmi2Status returned)
{
    fmi2Status s = returned > c->call_status ? returned : c->call_status;
    if (s == fmi2Pending) s = fmi2Error;
    if (s == fmi2Fatal) c->state = ST_FATAL;
    return s;
}

static const char *type_name(char t)
{
    switch (t) {
    case 'R': return "Real";
    case 'I': return "Integer";
    case 'E': return "Enumeration";
    case 'B': return "Boolean";
    case 'S': return "String";
    default: return "?";
    }
}

/* Value references, types and (for setters) which variables may be set in the current state. */
static int check_vrs(Component *c, const char *fn, const fmi2ValueReference vr[], size_t nvr,
                     const void *values, char type, int set)
{
    if (nvr > 0 && (!vr || !values)) {
        ds_logf(c, fmi2Error, "%s: %s is NULL for nvr = %zu", fn, !vr ? "vr" : "value", nvr);
        return 0;
    }
    for (size_t i = 0; i < nvr; ++i) {
        if (vr[i] >= DS_N_VR || !DS_VARIABLES[vr[i]].name) {
            ds_logf(c, fmi2Error, "%s: no variable has value reference %u (vr[%zu]); nothing done",
                    fn, vr[i], i);
            return 0;
        }
        const ds_variable *v = &DS_VARIABLES[vr[i]];
        const int ok_type = v->type == type || (type == 'I' && v->type == 'E');
        if (!ok_type) {
            ds_logf(c, fmi2Error, "%s: variable %s (value reference %u) is a%s %s, not a%s %s; "
                    "nothing done", fn, v->name, vr[i],
                    v->type == 'I' || v->type == 'E' ? "n" : "", type_name(v->type),
                    type == 'I' ? "n" : "", type_name(type));
            return 0;
        }
        if (!set) continue;
        if (v->causality == DS_OUTPUT) {
            ds_logf(c, fmi2Error, "%s: variable %s (value reference %u) is an output (computed by "
                    "the FMU) and cannot be set; nothing done", fn, v->name, vr[i]);
            return 0;
        }
        if (v->causality == DS_PARAMETER && c->state == ST_STEP_COMPLETE) {
            ds_logf(c, fmi2Error, "%s: parameter %s (value reference %u) is fixed: it can be set "
                    "only before fmi2ExitInitializationMode, not in state %s; nothing done", fn,
                    v->name, vr[i], ds_state_name(c->state));
            return 0;
        }
        if (type == 'B') {
            const fmi2Boolean b = ((const fmi2Boolean *)values)[i];
            if (b != fmi2True && b != fmi2False) {
                ds_logf(c, fmi2Error, "%s: value %d for %s is neither fmi2True (1) nor fmi2False "
                        "(0); nothing done", fn, b, v->name);
                return 0;
            }
        }
    }
    return 1;
}

/* ---- FMI functions: instantiation ------------------------------------------------------------ */
EXPORT const char *fmi2GetTypesPlatform(void) { return "default"; }
EXPORT const char *fmi2GetVersion(void) { return "2.0"; }

static void destroy(Component *c)
{
    if (!c) return;
    c->magic = 0;
    free(c->name);
    free(c->resources);
    free(c);
}

EXPORT fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                                     fmi2String fmuResourceLocation,
                                     const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                                     fmi2Boolean loggingOn)
{
    if (!functions) return NULL; /* nowhere to say why */
    Component *c = calloc(1, sizeof *c);
    if (!c) return NULL;
    c->magic = COMPONENT_MAGIC;
    c->name = strdup(instanceName && instanceName[0] ? instanceName : "?");
    c->host = *functions;
    c->logging_on = c->logging_on_at_instantiation = loggingOn != fmi2False;
    memset(c->category_on, 1, sizeof c->category_on);
    c->state = ST_INSTANTIATED;
    c->callbacks.logger = ds_slave_logger;
    c->callbacks.componentEnvironment = c;
    if (!c->name) {
        free(c);
        return NULL;
    }
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
    if (!fmuGUID || strcmp(fmuGUID, DS_GUID) != 0) {
        ds_logf(c, fmi2Error, "fmi2Instantiate: GUID %s does not match this FMU's %s (the "
                "modelDescription.xml of another build of %s?)", fmuGUID ? fmuGUID : "(NULL)",
                DS_GUID, DS_MODEL_IDENTIFIER);
        goto fail;
    }
    if (!(resources = ds_uri_to_path(fmuResourceLocation, err, ERR_LEN))) {
        ds_logf(c, fmi2Error, "fmi2Instantiate: %s", err);
        goto fail;
    }
    if (ds_check_resources(resources, err, ERR_LEN) != 0) {
        ds_logf(c, fmi2Error, "fmi2Instantiate: %s (fmuResourceLocation '%s')", err,
                fmuResourceLocation);
        goto fail;
    }
    if (ds_python_instantiate(c, resources, fmuGUID, visible) != 0) goto fail;
    c->resources = resources;
    free(err);
    return c;
fail:
    free(resources);
    free(err);
    destroy(c);
    return NULL;
}

EXPORT void fmi2FreeInstance(fmi2Component comp)
{
    Component *c = component(comp);
    if (!c) return;
    ds_python_free(c);
    destroy(c);
}

EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component comp, fmi2Boolean loggingOn,
                                      size_t nCategories, const fmi2String categories[])
{
    Component *c = component(comp);
    if (!begin(c, "fmi2SetDebugLogging", MASK_SetDebugLogging)) return fmi2Error;
    unsigned char on[DS_N_LOG_CATEGORIES + 1];
    memset(on, nCategories == 0, sizeof on);
    if (nCategories > 0 && !categories) {
        ds_logf(c, fmi2Error, "fmi2SetDebugLogging: categories is NULL for nCategories = %zu",
                nCategories);
        return fmi2Error;
    }
    for (size_t i = 0; i < nCategories; ++i) {
        const int k = ds_category_index(categories[i]);
        if (k < 0) {
            char known[512] = "";
            for (int j = 0; DS_LOG_CATEGORIES[j]; ++j)
                append_item(known, sizeof known, DS_LOG_CATEGORIES[j]);
            ds_logf(c, fmi2Error, "fmi2SetDebugLogging: unknown log category '%s' (declared: %s); "
                    "nothing changed", categories[i] ? categories[i] : "(NULL)", known);
            return fmi2Error;
        }
        on[k] = 1;
    }
    c->logging_on = loggingOn != fmi2False;
    memcpy(c->category_on, on, sizeof on);
    return fmi2OK;
}

/* A double as Python's repr writes it (the shortest digits that read back as the same double), as
   the Python side's messages do. */
static void repr_double(char *out, size_t n, double x)
{
    for (int digits = 1; digits <= 17; ++digits) {
        ds_format(out, n, "%.*g", digits, x);
        if (!isfinite(x) || strtod(out, NULL) == x) break;
    }
    if (isfinite(x) && !strpbrk(out, ".e")) ds_format(out + strlen(out), n - strlen(out), ".0");
}

/* The step [t, t + h] ends after the stop time the host defined (FMI 2.0, fmi2SetupExperiment:
   the FMU may not compute beyond it); a step that ends there up to rounding is allowed. */
static int past_stop_time(const Component *c, double t, double h)
{
    const double end = t + h, stop = c->stop_time, size = stop < 0.0 ? -stop : stop;
    return c->stop_defined && end > stop + 1e-9 * (size > 1.0 ? size : 1.0);
}

/* ---- FMI functions: the life cycle ----------------------------------------------------------- */
EXPORT fmi2Status fmi2SetupExperiment(fmi2Component comp, fmi2Boolean toleranceDefined,
                                      fmi2Real tolerance, fmi2Real startTime,
                                      fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    Component *c = component(comp);
    if (!begin(c, "fmi2SetupExperiment", MASK_SetupExperiment)) return fmi2Error;
    if (stopTimeDefined != fmi2False && !(stopTime >= startTime)) {
        char stop[40], start[40];
        repr_double(stop, sizeof stop, stopTime);
        repr_double(start, sizeof start, startTime);
        ds_logf(c, fmi2Error, "fmi2SetupExperiment: stop time %s is not at or after the start "
                "time %s; nothing changed", stop, start);
        return fmi2Error;
    }
    ds_fast_drop(c);
    const fmi2Status s = ds_finish(c, ds_pf.SetupExperiment(c->inner, toleranceDefined,
                                                            tolerance, startTime,
                                                            stopTimeDefined, stopTime));
    if (s <= fmi2Warning) {
        c->last_time = startTime;
        c->stop_defined = stopTimeDefined != fmi2False;
        c->stop_time = stopTime;
    }
    return s;
}

EXPORT fmi2Status fmi2EnterInitializationMode(fmi2Component comp)
{
    Component *c = component(comp);
    if (!begin(c, "fmi2EnterInitializationMode", MASK_EnterInitializationMode)) return fmi2Error;
    ds_fast_drop(c);
    const fmi2Status s = ds_finish(c, ds_pf.EnterInitializationMode(c->inner));
    if (s <= fmi2Warning) c->state = ST_INITIALIZATION;
    return s;
}

EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component comp)
{
    Component *c = component(comp);
    if (!begin(c, "fmi2ExitInitializationMode", MASK_ExitInitializationMode)) return fmi2Error;
    ds_fast_drop(c);
    const fmi2Status s = ds_finish(c, ds_pf.ExitInitializationMode(c->inner));
    if (s <= fmi2Warning) c->state = ST_STEP_COMPLETE;
    return s;
}

EXPORT fmi2Status fmi2Terminate(fmi2Component comp)
{
    Component *c = component(comp);
    if (!begin(c, "fmi2Terminate", MASK_Terminate)) return fmi2Error;
    ds_fast_drop(c);
    const fmi2Status s = ds_finish(c, ds_pf.Terminate(c->inner));
    if (s <= fmi2Warning) c->state = ST_TERMINATED;
    return s;
}

EXPORT fmi2Status fmi2Reset(fmi2Component comp)
{
    Component *c = component(comp);
    if (!begin(c, "fmi2Reset", MASK_Reset)) return fmi2Error;
    /* pythonfmu's reset makes a new slave from the resources folder: were it gone (the unpacked
       FMU moved or deleted), the old slave would be lost with fmi2Fatal. Checked first, the
       instance goes on as it was and a later fmi2Reset works once the folder is back. */
    char err[1024];
    if (ds_check_resources(c->resources, err, sizeof err) != 0) {
        ds_logf(c, fmi2Error, "fmi2Reset: %s: the FMU's folder was moved or deleted after "
                "fmi2Instantiate; nothing was reset (the instance goes on as it was): put the "
                "folder back and call fmi2Reset again", err);
        return fmi2Error;
    }
    const fmi2Status s = ds_python_reset(c);
    if (s <= fmi2Warning) {
        c->state = ST_INSTANTIATED;
        c->last_time = 0.0;
        c->stop_defined = 0;
        c->logging_on = c->logging_on_at_instantiation;
        memset(c->category_on, 1, sizeof c->category_on);
    }
    return s;
}

/* ---- FMI functions: values ------------------------------------------------------------------- */
#define GETTER(Name, CType, T)                                                                     \
    EXPORT fmi2Status fmi2Get##Name(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, \
                                    CType value[])                                                 \
    {                                                                                              \
        Component *c = component(comp);                                                            \
        if (!begin(c, "fmi2Get" #Name, MASK_Get)) return fmi2Error;                                \
        if (!check_vrs(c, "fmi2Get" #Name, vr, nvr, value, T, 0)) return fmi2Error;                \
        if (nvr == 0 || ds_fast_get(c, vr, nvr, (void *)value, T)) return fmi2OK;                  \
        ds_fast_drop(c);                                                                           \
        return ds_finish(c, ds_pf.Get##Name(c->inner, vr, nvr, value));                            \
    }
#define SETTER(Name, CType, T)                                                                     \
    EXPORT fmi2Status fmi2Set##Name(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, \
                                    const CType value[])                                           \
    {                                                                                              \
        Component *c = component(comp);                                                            \
        if (!begin(c, "fmi2Set" #Name, MASK_Set)) return fmi2Error;                                \
        if (!check_vrs(c, "fmi2Set" #Name, vr, nvr, value, T, 1)) return fmi2Error;                \
        if (nvr == 0) return fmi2OK;                                                               \
        if (T == 'R' && ds_fast_set_real(c, vr, nvr, (const fmi2Real *)(const void *)value))       \
            return fmi2OK;                                                                         \
        ds_fast_drop(c);                                                                           \
        return ds_finish(c, ds_pf.Set##Name(c->inner, vr, nvr, value));                            \
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
    Component *c = component(comp);
    if (!begin(c, "fmi2DoStep", MASK_DoStep)) return fmi2Error;
    if (past_stop_time(c, currentCommunicationPoint, communicationStepSize)) {
        char t[40], end[40], stop[40];
        repr_double(t, sizeof t, currentCommunicationPoint);
        repr_double(end, sizeof end, currentCommunicationPoint + communicationStepSize);
        repr_double(stop, sizeof stop, c->stop_time);
        ds_logf(c, fmi2Error, "fmi2DoStep: the step [%s, %s] ends after the stop time %s defined "
                "in fmi2SetupExperiment; nothing was computed", t, end, stop);
        return fmi2Error;
    }
    c->has_reached = 0;
    if (ds_fast_step(c, currentCommunicationPoint, communicationStepSize)) {
        c->last_time = currentCommunicationPoint + communicationStepSize;
        return fmi2OK;
    }
    ds_fast_drop(c);
    const fmi2Status s = ds_finish(c, ds_pf.DoStep(c->inner, currentCommunicationPoint,
                                                   communicationStepSize,
                                                   noSetFMUStatePriorToCurrentPoint));
    if (s == fmi2Discard) {
        c->state = ST_STEP_FAILED;
        c->last_time = c->has_reached ? c->reached : currentCommunicationPoint;
    } else if (s <= fmi2Warning) {
        c->last_time = currentCommunicationPoint + communicationStepSize;
    }
    return s;
}

EXPORT fmi2Status fmi2CancelStep(fmi2Component comp)
{
    Component *c = component(comp);
    begin(c, "fmi2CancelStep", MASK_CancelStep);
    return fmi2Error;
}

EXPORT fmi2Status fmi2GetStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Status *value)
{
    Component *c = component(comp);
    if (!begin(c, "fmi2GetStatus", MASK_Status)) return fmi2Error;
    (void)value;
    ds_logf(c, fmi2Discard, "fmi2GetStatus(%d): not available: fmi2DoStep never returns "
            "fmi2Pending", (int)s);
    return fmi2Discard;
}

EXPORT fmi2Status fmi2GetRealStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Real *value)
{
    Component *c = component(comp);
    if (!begin(c, "fmi2GetRealStatus", MASK_Status)) return fmi2Error;
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
    Component *c = component(comp);
    if (!begin(c, "fmi2GetIntegerStatus", MASK_Status)) return fmi2Error;
    (void)value;
    ds_logf(c, fmi2Discard, "fmi2GetIntegerStatus(%d): no integer status is available", (int)s);
    return fmi2Discard;
}

EXPORT fmi2Status fmi2GetBooleanStatus(fmi2Component comp, const fmi2StatusKind s,
                                       fmi2Boolean *value)
{
    Component *c = component(comp);
    if (!begin(c, "fmi2GetBooleanStatus", MASK_Status)) return fmi2Error;
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
    Component *c = component(comp);
    if (!begin(c, "fmi2GetStringStatus", MASK_Status)) return fmi2Error;
    (void)value;
    ds_logf(c, fmi2Discard, "fmi2GetStringStatus(%d): not available: fmi2DoStep never returns "
            "fmi2Pending", (int)s);
    return fmi2Discard;
}

EXPORT fmi2Status fmi2GetDirectionalDerivative(fmi2Component comp, const fmi2ValueReference u[],
                                               size_t nu, const fmi2ValueReference z[], size_t nz,
                                               const fmi2Real dv[], fmi2Real dz[])
{
    Component *c = component(comp);
    (void)u, (void)nu, (void)z, (void)nz, (void)dv, (void)dz;
    if (!begin(c, "fmi2GetDirectionalDerivative", MASK_DirectionalDerivative)) return fmi2Error;
    ds_logf(c, fmi2Error, "fmi2GetDirectionalDerivative: not provided "
            "(providesDirectionalDerivative is false)");
    return fmi2Error;
}

EXPORT fmi2Status fmi2SetRealInputDerivatives(fmi2Component comp, const fmi2ValueReference vr[],
                                              size_t nvr, const fmi2Integer order[],
                                              const fmi2Real value[])
{
    Component *c = component(comp);
    (void)vr, (void)nvr, (void)order, (void)value;
    if (!begin(c, "fmi2SetRealInputDerivatives", MASK_SetRealInputDerivatives)) return fmi2Error;
    ds_logf(c, fmi2Error, "fmi2SetRealInputDerivatives: not provided (canInterpolateInputs is "
            "false): inputs are held constant over each step");
    return fmi2Error;
}

EXPORT fmi2Status fmi2GetRealOutputDerivatives(fmi2Component comp, const fmi2ValueReference vr[],
                                               size_t nvr, const fmi2Integer order[],
                                               fmi2Real value[])
{
    Component *c = component(comp);
    (void)vr, (void)nvr, (void)order, (void)value;
    if (!begin(c, "fmi2GetRealOutputDerivatives", MASK_GetRealOutputDerivatives))
        return fmi2Error;
    ds_logf(c, fmi2Error, "fmi2GetRealOutputDerivatives: not provided "
            "(maxOutputDerivativeOrder is 0)");
    return fmi2Error;
}


/* ---- FMI functions: FMU states (states.c) ---------------------------------------------------- */
EXPORT fmi2Status fmi2GetFMUstate(fmi2Component comp, fmi2FMUstate *FMUstate)
{
    Component *c = component(comp);
    if (!begin(c, "fmi2GetFMUstate", MASK_FMUstate)) return fmi2Error;
    return ds_state_get(c, FMUstate);
}

EXPORT fmi2Status fmi2SetFMUstate(fmi2Component comp, fmi2FMUstate FMUstate)
{
    Component *c = component(comp);
    if (!begin(c, "fmi2SetFMUstate", MASK_FMUstate)) return fmi2Error;
    return ds_state_set(c, FMUstate);
}

EXPORT fmi2Status fmi2FreeFMUstate(fmi2Component comp, fmi2FMUstate *FMUstate)
{
    Component *c = component(comp);
    if (!begin(c, "fmi2FreeFMUstate", MASK_FMUstate)) return fmi2Error;
    return ds_state_free(c, FMUstate);
}

EXPORT fmi2Status fmi2SerializedFMUstateSize(fmi2Component comp, fmi2FMUstate FMUstate,
                                             size_t *size)
{
    Component *c = component(comp);
    if (!begin(c, "fmi2SerializedFMUstateSize", MASK_FMUstate)) return fmi2Error;
    return ds_state_size(c, FMUstate, size);
}

EXPORT fmi2Status fmi2SerializeFMUstate(fmi2Component comp, fmi2FMUstate FMUstate,
                                        fmi2Byte serializedState[], size_t size)
{
    Component *c = component(comp);
    if (!begin(c, "fmi2SerializeFMUstate", MASK_FMUstate)) return fmi2Error;
    return ds_state_serialize(c, FMUstate, serializedState, size);
}

EXPORT fmi2Status fmi2DeSerializeFMUstate(fmi2Component comp, const fmi2Byte serializedState[],
                                          size_t size, fmi2FMUstate *FMUstate)
{
    Component *c = component(comp);
    if (!begin(c, "fmi2DeSerializeFMUstate", MASK_FMUstate)) return fmi2Error;
    return ds_state_deserialize(c, serializedState, size, FMUstate);
}
