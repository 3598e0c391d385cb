/*
 * machine.c -- the co-simulation state machine and what both fronts share (drillstring_fmi2.h).
 *
 * Every FMI function of front.c (FMI 2.0) and front3.c (FMI 3.0) first checks the call against
 * the co-simulation state machine (FMI 2.0, section 4.2.4; FMI 3.0, section 4.2; in the style of
 * the Modelica Association's Reference FMUs: a mask of the states in which the standard allows the
 * call; otherwise fmi2Error with "illegal call sequence"), then what is structural (GUID or
 * instantiation token, value references, types, causality and variability against the state),
 * before anything reaches Python. What passes goes to the native fast path (fast.c) or to
 * pythonfmu's library. The Python slave reports problems as log messages (it never raises into
 * pythonfmu); the layer returns the worst status logged in the call, so a rejected value is an
 * error from the very call that received it, the value not applied.
 *
 * The FMI 3.0 twin's binary is compiled with DS_FMI3 defined: its messages name the FMI 3.0
 * calls, types and states (DS_FN); the logic is the same code.
 */
#define DS_MODEL_TABLES /* DS_VARIABLES and DS_LOG_CATEGORIES are defined here */
#include "drillstring_fmi2.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

const char *ds_state_name(int s)
{
    switch (s) {
    case ST_INSTANTIATED: return "Instantiated";
    case ST_INITIALIZATION: return "InitializationMode";
    case ST_STEP_COMPLETE: return DS_FN("StepComplete", "StepMode");
    case ST_STEP_FAILED: return DS_FN("StepFailed (after fmi2Discard)",
                                      "StepMode after fmi3Discard (until fmi3SetFMUState)");
    case ST_TERMINATED: return "Terminated";
    case ST_FATAL: return "Fatal";
    default: return "?";
    }
}

/* ---- call checks ----------------------------------------------------------------------------- */
Component *ds_component(void *handle)
{
    Component *c = handle;
    return (c && c->magic == COMPONENT_MAGIC) ? c : NULL;
}

void ds_append_item(char *out, size_t cap, const char *item)
{
    const size_t len = strlen(out);
    if (len + 1 < cap) ds_format(out + len, cap - len, "%s%s", len ? ", " : "", item);
}

static void allowed_states(int mask, char *out, size_t n)
{
    out[0] = '\0';
    for (int s = ST_INSTANTIATED; s <= ST_FATAL; s <<= 1)
        if (mask & s) ds_append_item(out, n, ds_state_name(s));
    if (!out[0]) ds_format(out, n, "%s", DS_FN("StepInProgress, which this FMU never enters",
                                               "a mode this FMU does not provide"));
}

int ds_begin(Component *c, const char *fn, int mask)
{
    if (!c) return 0;
    c->call_status = fmi2OK;
    c->call = fn;
    if (!(c->state & mask)) {
        char allowed[256];
        allowed_states(mask, allowed, sizeof allowed);
        ds_logf(c, fmi2Error, "%s: illegal call sequence: not allowed in state %s (allowed in: %s)",
                fn, ds_state_name(c->state), allowed);
        return 0;
    }
    return 1;
}

fmi2Status ds_finish(Component *c, fmi2Status returned)
{
    fmi2Status s = returned > c->call_status ? returned : c->call_status;
    if (s == fmi2Pending) s = fmi2Error;
    if (s == fmi2Fatal) c->state = ST_FATAL;
    return s;
}

/* The name of a type code as the FMI version names it, with its article. */
static const char *type_name(char t)
{
    switch (t) {
    case 'R': return DS_FN("a Real", "a Float64");
    case 'I': return DS_FN("an Integer", "an Int32");
    case 'E': return DS_FN("an Enumeration", "an Enumeration (Int64)");
    case 'B': return "a Boolean";
    case 'S': return "a String";
    default: return "?";
    }
}

int ds_check_vrs(Component *c, const char *fn, const fmi2ValueReference vr[], size_t nvr,
                 const void *values, char type, int set)
{
    if (nvr > 0 && (!vr || !values)) {
        ds_logf(c, fmi2Error, "%s: %s is NULL for %s = %zu", fn, !vr ? DS_FN("vr", "valueReferences")
                : DS_FN("value", "values"), DS_FN("nvr", "nValueReferences"), nvr);
        return 0;
    }
    for (size_t i = 0; i < nvr; ++i) {
        if (vr[i] >= DS_N_VR || !DS_VARIABLES[vr[i]].name) {
            ds_logf(c, fmi2Error, "%s: no variable has value reference %u (%s[%zu]); nothing done",
                    fn, vr[i], DS_FN("vr", "valueReferences"), i);
            return 0;
        }
        const ds_variable *v = &DS_VARIABLES[vr[i]];
#ifdef DS_FMI3
        const int ok_type = v->type == type; /* an Enumeration is an Int64 in FMI 3.0 */
#else
        const int ok_type = v->type == type || (type == 'I' && v->type == 'E');
#endif
        if (!ok_type) {
            ds_logf(c, fmi2Error, "%s: variable %s (value reference %u) is %s, not %s; nothing "
                    "done", fn, v->name, vr[i], type_name(v->type), type_name(type));
            return 0;
        }
        if (!set) continue;
        if (v->causality == DS_INDEPENDENT) {
            ds_logf(c, fmi2Error, "%s: variable %s (value reference %u) is the independent "
                    "variable (the FMU's time, which the steps advance) and cannot be set; "
                    "nothing done", fn, v->name, vr[i]);
            return 0;
        }
        if (v->causality == DS_OUTPUT) {
            ds_logf(c, fmi2Error, "%s: variable %s (value reference %u) is an output (computed by "
                    "the FMU) and cannot be set; nothing done", fn, v->name, vr[i]);
            return 0;
        }
        if (v->causality == DS_PARAMETER && c->state == ST_STEP_COMPLETE) {
            ds_logf(c, fmi2Error, "%s: parameter %s (value reference %u) is fixed: it can be set "
                    "only before %s, not in state %s; nothing done", fn, v->name, vr[i],
                    DS_FN("fmi2ExitInitializationMode", "fmi3ExitInitializationMode"),
                    ds_state_name(c->state));
            return 0;
        }
        if (type == 'B') {
            const fmi2Boolean b = ((const fmi2Boolean *)values)[i];
            if (b != fmi2True && b != fmi2False) {
                ds_logf(c, fmi2Error, "%s: value %d for %s is neither %s (1) nor %s (0); nothing "
                        "done", fn, b, v->name, DS_FN("fmi2True", "fmi3True"),
                        DS_FN("fmi2False", "fmi3False"));
                return 0;
            }
        }
    }
    return 1;
}

/* ---- instances ------------------------------------------------------------------------------- */
void ds_destroy(Component *c)
{
    if (!c) return;
    c->magic = 0;
    free(c->name);
    free(c->resources);
    free(c);
}

Component *ds_new_component(const char *instanceName, int loggingOn)
{
    Component *c = calloc(1, sizeof *c);
    if (!c) return NULL;
    c->magic = COMPONENT_MAGIC;
    c->name = strdup(instanceName && instanceName[0] ? instanceName : "?");
    c->logging_on = c->logging_on_at_instantiation = loggingOn != 0;
    memset(c->category_on, 1, sizeof c->category_on);
    c->state = ST_INSTANTIATED;
    c->call = DS_FN_INSTANTIATE;
    c->callbacks.logger = ds_slave_logger;
    c->callbacks.componentEnvironment = c;
    if (!c->name) {
        free(c);
        return NULL;
    }
    return c;
}

int ds_check_token(Component *c, const char *token)
{
    if (token && strcmp(token, DS_GUID) == 0) return 0;
    ds_logf(c, fmi2Error, "%s: %s %s does not match this FMU's %s (the modelDescription.xml of "
            "another build of %s?)", DS_FN_INSTANTIATE, DS_FN("GUID", "instantiationToken"),
            token ? token : "(NULL)", DS_GUID, DS_MODEL_IDENTIFIER);
    return -1;
}

int ds_start(Component *c, const char *location, char *resources, int visible)
{
    char *err = malloc(ERR_LEN); /* on the heap: hosts' threads may have small stacks */
    if (!err) {
        ds_logf(c, fmi2Error, "%s: out of memory", DS_FN_INSTANTIATE);
        return -1;
    }
    const int checked = ds_check_resources(resources, err, ERR_LEN);
    if (checked != 0)
        ds_logf(c, fmi2Error, "%s: %s (%s '%s')", DS_FN_INSTANTIATE, err,
                DS_FN("fmuResourceLocation", "resourcePath"), location);
    free(err);
    if (checked != 0 || ds_python_instantiate(c, resources, DS_GUID, visible) != 0) return -1;
    c->resources = resources;
    return 0;
}

void ds_free(Component *c)
{
    ds_python_free(c);
    ds_destroy(c);
}

fmi2Status ds_set_debug_logging(Component *c, const char *fn, int loggingOn, size_t nCategories,
                                const fmi2String categories[])
{
    unsigned char on[DS_N_LOG_CATEGORIES + 1];
    memset(on, nCategories == 0, sizeof on);
    if (nCategories > 0 && !categories) {
        ds_logf(c, fmi2Error, "%s: categories is NULL for nCategories = %zu", fn, nCategories);
        return fmi2Error;
    }
    for (size_t i = 0; i < nCategories; ++i) {
        const int k = ds_category_index(categories[i]);
        if (k < 0) {
            char known[512] = "";
            for (int j = 0; DS_LOG_CATEGORIES[j]; ++j)
                ds_append_item(known, sizeof known, DS_LOG_CATEGORIES[j]);
            ds_logf(c, fmi2Error, "%s: unknown log category '%s' (declared: %s); nothing changed",
                    fn, categories[i] ? categories[i] : "(NULL)", known);
            return fmi2Error;
        }
        on[k] = 1;
    }
    c->logging_on = loggingOn != 0;
    memcpy(c->category_on, on, sizeof on);
    return fmi2OK;
}

/* A double as Python's repr writes it (the shortest digits that read back as the same double), as
   the Python side's messages do. */
void ds_repr_double(char *out, size_t n, double x)
{
    for (int digits = 1; digits <= 17; ++digits) {
        ds_format(out, n, "%.*g", digits, x);
        if (!isfinite(x) || strtod(out, NULL) == x) break;
    }
    if (isfinite(x) && !strpbrk(out, ".e")) ds_format(out + strlen(out), n - strlen(out), ".0");
}

/* The step [t, t + h] ends after the stop time the host defined (the FMU may not compute beyond
   it); a step that ends there up to rounding is allowed. */
static int past_stop_time(const Component *c, double t, double h)
{
    const double end = t + h, stop = c->stop_time, size = stop < 0.0 ? -stop : stop;
    return c->stop_defined && end > stop + 1e-9 * (size > 1.0 ? size : 1.0);
}

/* ---- the life cycle -------------------------------------------------------------------------- */
fmi2Status ds_setup_experiment(Component *c, const char *fn, int toleranceDefined,
                               double tolerance, double startTime, int stopTimeDefined,
                               double stopTime)
{
    if (stopTimeDefined && !(stopTime >= startTime)) {
        char stop[40], start[40];
        ds_repr_double(stop, sizeof stop, stopTime);
        ds_repr_double(start, sizeof start, startTime);
        ds_logf(c, fmi2Error, "%s: stop time %s is not at or after the start time %s; nothing "
                "changed", fn, stop, start);
        return fmi2Error;
    }
    ds_fast_drop(c);
    const fmi2Status s = ds_finish(c, ds_pf.SetupExperiment(c->inner, toleranceDefined, tolerance,
                                                            startTime, stopTimeDefined, stopTime));
    if (s <= fmi2Warning) {
        c->last_time = startTime;
        c->stop_defined = stopTimeDefined != 0;
        c->stop_time = stopTime;
    }
    return s;
}

fmi2Status ds_enter_initialization(Component *c)
{
    ds_fast_drop(c);
    const fmi2Status s = ds_finish(c, ds_pf.EnterInitializationMode(c->inner));
    if (s <= fmi2Warning) c->state = ST_INITIALIZATION;
    return s;
}

fmi2Status ds_exit_initialization(Component *c)
{
    ds_fast_drop(c);
    const fmi2Status s = ds_finish(c, ds_pf.ExitInitializationMode(c->inner));
    if (s <= fmi2Warning) c->state = ST_STEP_COMPLETE;
    return s;
}

fmi2Status ds_terminate(Component *c)
{
    ds_fast_drop(c);
    const fmi2Status s = ds_finish(c, ds_pf.Terminate(c->inner));
    if (s <= fmi2Warning) c->state = ST_TERMINATED;
    return s;
}

fmi2Status ds_reset(Component *c, const char *fn)
{
    /* pythonfmu's reset makes a new slave from the resources folder: were it gone (the unpacked
       FMU moved or deleted), the old slave would be lost with fmi2Fatal. Checked first, the
       instance goes on as it was and a later reset works once the folder is back. */
    char err[1024];
    if (ds_check_resources(c->resources, err, sizeof err) != 0) {
        ds_logf(c, fmi2Error, "%s: %s: the FMU's folder was moved or deleted after %s; nothing was "
                "reset (the instance goes on as it was): put the folder back and call %s again",
                fn, err, DS_FN_INSTANTIATE, fn);
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

/* ---- values ---------------------------------------------------------------------------------- */
fmi2Status ds_get(Component *c, const fmi2ValueReference vr[], size_t nvr, void *value, char type)
{
    if (nvr == 0 || ds_fast_get(c, vr, nvr, value, type)) return fmi2OK;
    ds_fast_drop(c);
    switch (type) {
    case 'R': return ds_finish(c, ds_pf.GetReal(c->inner, vr, nvr, value));
    case 'I': return ds_finish(c, ds_pf.GetInteger(c->inner, vr, nvr, value));
    case 'B': return ds_finish(c, ds_pf.GetBoolean(c->inner, vr, nvr, value));
    default: return ds_finish(c, ds_pf.GetString(c->inner, vr, nvr, value));
    }
}

fmi2Status ds_set(Component *c, const fmi2ValueReference vr[], size_t nvr, const void *value,
                  char type)
{
    if (nvr == 0) return fmi2OK;
    if (type == 'R' && ds_fast_set_real(c, vr, nvr, value)) return fmi2OK;
    ds_fast_drop(c);
    switch (type) {
    case 'R': return ds_finish(c, ds_pf.SetReal(c->inner, vr, nvr, value));
    case 'I': return ds_finish(c, ds_pf.SetInteger(c->inner, vr, nvr, value));
    case 'B': return ds_finish(c, ds_pf.SetBoolean(c->inner, vr, nvr, value));
    default: return ds_finish(c, ds_pf.SetString(c->inner, vr, nvr, value));
    }
}

/* ---- stepping -------------------------------------------------------------------------------- */
fmi2Status ds_do_step(Component *c, const char *fn, double t, double h, int noSetPrior)
{
    if (past_stop_time(c, t, h)) {
        char start[40], end[40], stop[40];
        ds_repr_double(start, sizeof start, t);
        ds_repr_double(end, sizeof end, t + h);
        ds_repr_double(stop, sizeof stop, c->stop_time);
        ds_logf(c, fmi2Error, "%s: the step [%s, %s] ends after the stop time %s defined in %s; "
                "nothing was computed", fn, start, end, stop,
                DS_FN("fmi2SetupExperiment", "fmi3EnterInitializationMode"));
        return fmi2Error;
    }
    c->has_reached = 0;
    if (ds_fast_step(c, t, h)) {
        c->last_time = t + h;
        return fmi2OK;
    }
    ds_fast_drop(c);
    const fmi2Status s = ds_finish(c, ds_pf.DoStep(c->inner, t, h, noSetPrior));
    if (s == fmi2Discard) {
        c->state = ST_STEP_FAILED;
        c->last_time = c->has_reached ? c->reached : t;
    } else if (s <= fmi2Warning) {
        c->last_time = t + h;
    }
    return s;
}
