/*
 * fast.c -- the native fast path (drillstring_fmi2.h).
 *
 * At the end of each of its calls while stepping, the Python slave hands the layer a descriptor
 * through a typed call (ds_front_fast, whose address the layer gave the Python side at
 * fmi2Instantiate, see runtime.c): a float64 block `io` it shares with this layer and its length,
 * compiled functions (numba cfuncs of drillstring.model.native) that step the model and compute
 * its outputs on that block and the kernel's arrays, and the io slots of the inputs and outputs.
 * The layer checks all of it against the model's table and the block's length, and then serves
 * fmi2SetReal of the inputs, fmi2DoStep and fmi2GetReal/fmi2GetInteger of the outputs in C,
 * setting io[FAST_STALE] so that Python takes the new state at its next call. Whatever it cannot
 * serve goes to Python as before; it drops the descriptor before every call into Python (the
 * arrays may be replaced there) and uses only the one handed over at the end of that call.
 */
#include "drillstring_fmi2.h"

#include <math.h>
#include <stdlib.h>

/* The descriptor, 64-bit words: magic, version, io, io's length (doubles), args, step, outputs,
   n_in, n_out; then n_in (value reference, slot) and n_out (value reference, slot, type 0 Real /
   1 Integer). drillstring_fmu_support.py writes it (_FAST_MAGIC, _FAST_VERSION). */
#define FAST_MAGIC 0x44534650ULL /* "DSFP" */
#define FAST_VERSION 2ULL
enum { D_MAGIC, D_VERSION, D_IO, D_IO_LEN, D_ARGS, D_STEP, D_OUTPUTS, D_N_IN, D_N_OUT, D_HEAD };
#define FAST_IO_MAX (1u << 20) /* doubles: far above any model's block, far below INT_MAX */
enum { FAST_STALE = 0, FAST_RESUME = 1, FAST_TIME = 2, FAST_NSTEPS = 3, FAST_BASE = 4 };
enum { FAST_DONE = 0, FAST_NOT_STARTED = 1, FAST_RESUMED = 2 };    /* results of a native step */

/* The descriptor refused: a warning naming why, counted into the status of the call that handed
   it over (its results are right, the slave serves every call from now on). */
__attribute__((format(printf, 2, 3))) static int32_t refuse(Component *c, const char *fmt, ...)
{
    char why[512];
    va_list args;
    va_start(args, fmt);
    const int n = vsnprintf(why, sizeof why, fmt, args);
    va_end(args);
    if (n < 0 || (size_t)n >= sizeof why) ds_format(why + sizeof why - 4, 4, "...");
    ds_logf(c, fmi2Warning, "the native fast path is refused: %s; the Python slave serves every "
            "call of %s", why, c->name);
    return 1;
}

/* A value reference of the descriptor: a variable of the model with this causality and type. */
static const char *bad_variable(uint64_t vr, unsigned char causality, char type)
{
    if (vr >= DS_N_VR || !DS_VARIABLES[vr].name) return "no variable of the model";
    const ds_variable *v = &DS_VARIABLES[vr];
    if (v->causality != causality) return causality == DS_INPUT ? "not an input" : "not an output";
    const int ok = v->type == type || (type == 'I' && v->type == 'E');
    return ok ? NULL : (type == 'R' ? "not a Real" : "not an Integer");
}

int32_t ds_front_fast(void *component, const uint64_t *d, size_t length)
{
    Component *c = component;
    if (!c || c->magic != COMPONENT_MAGIC) return -1;
    Fast *f = &c->fast, next;
    f->on = 0;
    if (!d || length < D_HEAD)
        return refuse(c, "a descriptor of %zu words, the header alone has %d", d ? length : 0,
                      (int)D_HEAD);
    if (d[D_MAGIC] != FAST_MAGIC || d[D_VERSION] != FAST_VERSION)
        return refuse(c, "magic %#llx version %llu, this layer reads %#llx version %llu",
                      (unsigned long long)d[D_MAGIC], (unsigned long long)d[D_VERSION],
                      FAST_MAGIC, FAST_VERSION);
    const uint64_t n_in = d[D_N_IN], n_out = d[D_N_OUT], io_len = d[D_IO_LEN];
    if (n_in > DS_N_VR || n_out > DS_N_VR)
        return refuse(c, "%llu inputs and %llu outputs, the model has %d variables",
                      (unsigned long long)n_in, (unsigned long long)n_out, DS_N_VR);
    const uint64_t need = D_HEAD + 2 * n_in + 3 * n_out;
    if (length != need)
        return refuse(c, "a descriptor of %zu words, %llu inputs and %llu outputs need %llu",
                      length, (unsigned long long)n_in, (unsigned long long)n_out,
                      (unsigned long long)need);
    if (!d[D_IO] || io_len < FAST_BASE || io_len > FAST_IO_MAX)
        return refuse(c, "an io block at %#llx of %llu doubles (at least %d, at most %u)",
                      (unsigned long long)d[D_IO], (unsigned long long)io_len, (int)FAST_BASE,
                      FAST_IO_MAX);
    if (!d[D_STEP]) return refuse(c, "no step function");
    for (int i = 0; i < DS_N_VR; ++i) next.in_slot[i] = next.out_slot[i] = -1;
    const uint64_t *p = d + D_HEAD;
    for (uint64_t i = 0; i < n_in; ++i, p += 2) {
        const char *bad = bad_variable(p[0], DS_INPUT, 'R');
        if (bad) return refuse(c, "input %llu: value reference %llu is %s", (unsigned long long)i,
                               (unsigned long long)p[0], bad);
        if (p[1] < FAST_BASE || p[1] >= io_len)
            return refuse(c, "input %s: slot %llu outside [%d, %llu)", DS_VARIABLES[p[0]].name,
                          (unsigned long long)p[1], (int)FAST_BASE, (unsigned long long)io_len);
        if (next.in_slot[p[0]] >= 0) return refuse(c, "input %s twice", DS_VARIABLES[p[0]].name);
        next.in_slot[p[0]] = (int)p[1];
    }
    for (uint64_t i = 0; i < n_out; ++i, p += 3) {
        if (p[2] > 1)
            return refuse(c, "output %llu: type code %llu (0 Real, 1 Integer)",
                          (unsigned long long)i, (unsigned long long)p[2]);
        const char type = p[2] == 0 ? 'R' : 'I';
        const char *bad = bad_variable(p[0], DS_OUTPUT, type);
        if (bad) return refuse(c, "output %llu: value reference %llu is %s", (unsigned long long)i,
                               (unsigned long long)p[0], bad);
        if (p[1] < FAST_BASE || p[1] >= io_len)
            return refuse(c, "output %s: slot %llu outside [%d, %llu)", DS_VARIABLES[p[0]].name,
                          (unsigned long long)p[1], (int)FAST_BASE, (unsigned long long)io_len);
        if (next.out_slot[p[0]] >= 0)
            return refuse(c, "output %s twice", DS_VARIABLES[p[0]].name);
        next.out_slot[p[0]] = (int)p[1];
        next.out_type[p[0]] = type;
    }
    next.io = (double *)(uintptr_t)d[D_IO];
    next.args = (void **)(uintptr_t)d[D_ARGS];
    next.step = (ds_native_fn)(uintptr_t)d[D_STEP];
    next.outputs = (ds_native_fn)(uintptr_t)d[D_OUTPUTS];
    next.outputs_stale = 1;
    next.on = 1;
    *f = next;
    return 0;
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
