/* The master's fixed-step Jacobi loop, in C (drillstring.orchestration.native_loop builds and
 * calls it).
 *
 * Per macro step k, exactly the calls of the Python loop (orchestration/fixed.py run_fixed,
 * step.py JacobiStep.advance, exchange.py Exchange.exchange, recorder.py Recorder.record), in
 * the same order and with the same arguments:
 *   0. linear extrapolation, from the second step on: held = y + (y - y_prev) * c with
 *      c = 0.5 h[k] / h[k-1] (the same operations as numpy's; compiled without contraction into
 *      fused multiply-adds), each unit's inputs set from held; y_prev = y;
 *   1. fmi2DoStep(unit, t[k], h[k], noSetFMUStatePriorToCurrentPoint) of every unit in order;
 *   2. the exchange after a step: each batch in order, a get into its slice of y, a set from
 *      the values y[idx[j]] gathered into its buffer;
 *   3. the row of t[k+1]: time, y, then each batch of recorded variables read and scattered
 *      into its columns (Integer and Boolean converted to double).
 * The first call that returns more than fmi2Warning stops the loop: the caller learns where
 * (phase, batch, status) and reports it as the Python loop does. Apart from step 0 nothing is
 * computed on the values: they are copied, so the results are the Python loop's bits.
 *
 * A batch is 7 words: function, component, value references, count, buffer, index array
 * (sets: source positions in y; recorded variables: destination columns; gets into y: 0),
 * kind (KIND_*). */

#include <stddef.h>
#include <stdint.h>

typedef int (*do_step_fn)(void *, double, double, int);
typedef int (*get_real_fn)(void *, const unsigned int *, size_t, double *);
typedef int (*set_real_fn)(void *, const unsigned int *, size_t, const double *);
typedef int (*get_int_fn)(void *, const unsigned int *, size_t, int *);

enum { KIND_GET_REAL = 0, KIND_SET_REAL = 1, KIND_GET_INT = 2 };
enum { PHASE_DO_STEP = 1, PHASE_EXCHANGE = 2, PHASE_RECORD = 3, PHASE_INPUTS = 4 };
enum { OP_WORDS = 7 };

static int call(const uint64_t *op, const double *y, double *row) {
    void *fn = (void *)(uintptr_t)op[0];
    void *comp = (void *)(uintptr_t)op[1];
    const unsigned int *vr = (const unsigned int *)(uintptr_t)op[2];
    size_t n = (size_t)op[3];
    const int64_t *idx = (const int64_t *)(uintptr_t)op[5];
    int st;
    if (op[6] == KIND_SET_REAL) {
        double *buf = (double *)(uintptr_t)op[4];
        for (size_t j = 0; j < n; j++) buf[j] = y[idx[j]];
        return ((set_real_fn)fn)(comp, vr, n, buf);
    }
    if (op[6] == KIND_GET_REAL) {
        double *buf = (double *)(uintptr_t)op[4];
        st = ((get_real_fn)fn)(comp, vr, n, buf);
        if (st <= 1 && idx != NULL)
            for (size_t j = 0; j < n; j++) row[idx[j]] = buf[j];
        return st;
    }
    int *ibuf = (int *)(uintptr_t)op[4];
    st = ((get_int_fn)fn)(comp, vr, n, ibuf);
    if (st <= 1)
        for (size_t j = 0; j < n; j++) row[idx[j]] = (double)ibuf[j];
    return st;
}

/* Steps k0 .. k1-1 (step k from t[k] over h[k]); the row of step k is rows[(row0 + k - k0)].
 * units: n_units pairs (fmi2DoStep, component); xops: the exchange's batches; rops: the
 * recorded variables' batches; iops: each unit's input batch, set from held (y_prev, held: ny
 * doubles; y_prev holds y of the step before k0) when linear is 1. Returns the number of steps
 * done (recorded); on a failure fail = {phase, index of the unit or batch, status}, else fail is
 * untouched. */
int64_t ds_master_loop(const uint64_t *units, int64_t n_units, const uint64_t *xops,
                       int64_t n_xops, const uint64_t *rops, int64_t n_rops,
                       const uint64_t *iops, int64_t n_iops, int linear, double *y_prev,
                       double *held, double *y, int64_t ny, const double *t, const double *h,
                       int64_t k0, int64_t k1, double *rows, int64_t row0, int64_t n_cols, int nsp,
                       int64_t *fail) {
    for (int64_t k = k0; k < k1; k++) {
        if (linear && k > 0) {
            double c = 0.5 * h[k] / h[k - 1];
            for (int64_t j = 0; j < ny; j++) held[j] = y[j] + (y[j] - y_prev[j]) * c;
            for (int64_t i = 0; i < n_iops; i++) {
                int st = call(iops + OP_WORDS * i, held, NULL);
                if (st > 1) {
                    fail[0] = PHASE_INPUTS, fail[1] = i, fail[2] = st;
                    return k - k0;
                }
            }
        }
        if (linear)
            for (int64_t j = 0; j < ny; j++) y_prev[j] = y[j];
        for (int64_t i = 0; i < n_units; i++) {
            void *comp = (void *)(uintptr_t)units[2 * i + 1];
            int st = ((do_step_fn)(uintptr_t)units[2 * i])(comp, t[k], h[k], nsp);
            if (st > 1) {
                fail[0] = PHASE_DO_STEP, fail[1] = i, fail[2] = st;
                return k - k0;
            }
        }
        for (int64_t i = 0; i < n_xops; i++) {
            int st = call(xops + OP_WORDS * i, y, NULL);
            if (st > 1) {
                fail[0] = PHASE_EXCHANGE, fail[1] = i, fail[2] = st;
                return k - k0;
            }
        }
        double *row = rows + (row0 + (k - k0)) * n_cols;
        row[0] = t[k + 1];
        for (int64_t j = 0; j < ny; j++) row[1 + j] = y[j];
        for (int64_t i = 0; i < n_rops; i++) {
            int st = call(rops + OP_WORDS * i, y, row);
            if (st > 1) {
                fail[0] = PHASE_RECORD, fail[1] = i, fail[2] = st;
                return k - k0;
            }
        }
    }
    return k1 - k0;
}
