/*
 * fast.c -- the native fast path (drillstring_fmi2.h).
 *
 * The Python slave announces, at the end of each of its calls while stepping, a descriptor (a
 * record "fast <address>"): a float64 block `io` it shares with this layer, compiled functions
 * (numba cfuncs of drillstring.model.native) that step the model and compute its outputs on that
 * block and the kernel's arrays, and the io slots of the inputs and outputs. The layer then serves
 * fmi2SetReal of the inputs, fmi2DoStep and fmi2GetReal/fmi2GetInteger of the outputs in C, and
 * sets io[FAST_STALE] so that Python takes the new state at its next call. Whatever it cannot
 * serve goes to Python as before; it drops the descriptor before every call into Python (the
 * arrays may be replaced there) and uses only the one announced at the end of that call.
 */
#include "drillstring_fmi2.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>

#define FAST_MAGIC 0x44534650ULL /* "DSFP" */
#define FAST_VERSION 1ULL
enum { FAST_STALE = 0, FAST_RESUME = 1, FAST_TIME = 2, FAST_NSTEPS = 3 }; /* every FMU's io */
enum { FAST_DONE = 0, FAST_NOT_STARTED = 1, FAST_RESUMED = 2 };    /* results of a native step */

/* The descriptor a slave announced: magic, version, io, args, step, outputs, n_in, n_out, then
   n_in (value reference, slot) and n_out (value reference, slot, type 0 Real / 1 Integer). */
static void fast_load(Component *c, const uint64_t *d)
{
    Fast *f = &c->fast;
    f->on = 0;
    if (!d || d[0] != FAST_MAGIC || d[1] != FAST_VERSION || !d[2] || !d[4]) return;
    const uint64_t n_in = d[6], n_out = d[7];
    if (n_in > FAST_MAX || n_out > FAST_MAX) return;
    for (int i = 0; i < DS_N_VR; ++i) f->in_slot[i] = f->out_slot[i] = -1;
    const uint64_t *p = d + 8;
    for (uint64_t i = 0; i < n_in; ++i, p += 2) {
        if (p[0] >= DS_N_VR || DS_VARIABLES[p[0]].type != 'R') return;
        f->in_slot[p[0]] = (int)p[1];
    }
    for (uint64_t i = 0; i < n_out; ++i, p += 3) {
        if (p[0] >= DS_N_VR || p[2] > 1) return;
        f->out_slot[p[0]] = (int)p[1];
        f->out_type[p[0]] = p[2] == 0 ? 'R' : 'I';
    }
    f->io = (double *)(uintptr_t)d[2];
    f->args = (void **)(uintptr_t)d[3];
    f->step = (ds_native_fn)(uintptr_t)d[4];
    f->outputs = (ds_native_fn)(uintptr_t)d[5];
    f->outputs_stale = 1;
    f->on = 1;
}

void ds_fast_record(Component *c, const char *text)
{
    char *end = NULL;
    errno = 0;
    const unsigned long long addr = strtoull(text, &end, 10);
    if (end && *end == '\0' && errno == 0) fast_load(c, (const uint64_t *)(uintptr_t)addr);
}

void ds_fast_drop(Component *c) { c->fast.on = 0; }

/* Outputs (and inputs, for fmi2GetReal) from the native block, if every value reference is one it
   serves; 0: Python serves the call. */
int ds_fast_get(Component *c, const fmi2ValueReference vr[], size_t nvr, void *value, char type)
{
    Fast *f = &c->fast;
    if (!f->on || c->state != ST_STEP_COMPLETE || (type != 'R' && type != 'I')) return 0;
    for (size_t i = 0; i < nvr; ++i) {
        const unsigned r = vr[i];
        if (f->out_slot[r] >= 0 ? f->out_type[r] != type : !(type == 'R' && f->in_slot[r] >= 0))
            return 0;
    }
    if (f->outputs && f->outputs_stale) {
        f->outputs(f->io, f->args, 0.0, 0.0);
        f->outputs_stale = 0;
    }
    for (size_t i = 0; i < nvr; ++i) {
        const unsigned r = vr[i];
        const double x = f->io[f->out_slot[r] >= 0 ? f->out_slot[r] : f->in_slot[r]];
        if (type == 'R') ((fmi2Real *)value)[i] = x;
        else ((fmi2Integer *)value)[i] = (fmi2Integer)x;
    }
    return 1;
}

/* Finite values of inputs into the native block (Python checks and names anything else). */
int ds_fast_set_real(Component *c, const fmi2ValueReference vr[], size_t nvr,
                     const fmi2Real value[])
{
    Fast *f = &c->fast;
    if (!f->on || c->state != ST_STEP_COMPLETE) return 0;
    for (size_t i = 0; i < nvr; ++i)
        if (f->in_slot[vr[i]] < 0 || !isfinite(value[i])) return 0;
    for (size_t i = 0; i < nvr; ++i) f->io[f->in_slot[vr[i]]] = value[i];
    f->io[FAST_STALE] = 1.0;
    f->outputs_stale = 1;
    return 1;
}

int ds_fast_step(Component *c, double t, double h)
{
    Fast *f = &c->fast;
    if (!f->on || !f->step) return 0;
    /* the checks of the Python step wrapper that reject a call; Python names the error */
    const double now = f->io[FAST_TIME];
    const double scale = fabs(now) > 1.0 ? fabs(now) : 1.0;
    if (!(isfinite(t) && isfinite(h) && h > 0.0 && !(fabs(t - now) > 1e-9 * scale))) return 0;
    const int32_t r = f->step(f->io, f->args, t, h);
    if (r == FAST_DONE) {
        f->io[FAST_TIME] = t + h;
        f->io[FAST_STALE] = 1.0;
        f->io[FAST_NSTEPS] += 1.0;
        f->outputs_stale = 1;
        return 1;
    }
    if (r == FAST_RESUMED) f->io[FAST_STALE] = 1.0; /* Python finishes the step */
    return 0;
}
