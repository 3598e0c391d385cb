/*
 * host3.c -- a minimal FMI 3.0 co-simulation host in plain C: one FMU, fixed steps, CSV.
 *
 * Loads binaries/x86_64-linux/<MODELIDENTIFIER>.so of an unpacked FMI 3.0 co-simulation FMU with
 * dlopen() (no Python, no libpython preloaded: the drillstring FMUs start Python themselves),
 * instantiates it with the native resource path, runs fmi3EnterInitializationMode (start 0, no
 * stop time), fmi3ExitInitializationMode and N steps of H on libcosim's grid (t_k = k*H_ns/1e9,
 * h_k = t_{k+1} - t_k), and writes after each step the time and the Float64 values of the given
 * value references, with 17 significant digits, one row per step. The test of the FMI 3.0 twins
 * (tests/test_fmu3.py) runs it in a clean environment.
 *
 * Usage: host3 UNZIPDIR MODELIDENTIFIER TOKEN H_NS N CSV VR [VR ...]. Exit status 0, 1 if an FMU
 * call fails (the FMU's messages on stderr say why), 2 on a usage error.
 */
#define _POSIX_C_SOURCE 200809L
#include <dlfcn.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef void *fmi3Instance;
typedef uint32_t fmi3ValueReference;
typedef enum { fmi3OK, fmi3Warning, fmi3Discard, fmi3Error, fmi3Fatal } fmi3Status;
typedef void (*fmi3LogMessageCallback)(void *, fmi3Status, const char *, const char *);
typedef fmi3Instance (*InstantiateCS)(const char *, const char *, const char *, bool, bool, bool,
                                      bool, const fmi3ValueReference *, size_t, void *,
                                      fmi3LogMessageCallback, void *);
typedef fmi3Status (*EnterInit)(fmi3Instance, bool, double, double, bool, double);
typedef fmi3Status (*Plain)(fmi3Instance);
typedef fmi3Status (*DoStep)(fmi3Instance, double, double, bool, bool *, bool *, bool *, double *);
typedef fmi3Status (*GetFloat64)(fmi3Instance, const fmi3ValueReference *, size_t, double *,
                                 size_t);
typedef void (*FreeInstance)(fmi3Instance);

static void logger(void *env, fmi3Status status, const char *category, const char *message)
{
    (void)env;
    fprintf(stderr, "[%d %s] %s\n", (int)status, category ? category : "", message);
}

static void *symbol(void *lib, const char *name)
{
    void *f = dlsym(lib, name);
    if (!f) fprintf(stderr, "host3: %s missing: %s\n", name, dlerror());
    return f;
}

int main(int argc, char **argv)
{
    if (argc < 8) {
        fprintf(stderr, "usage: host3 UNZIPDIR MODELIDENTIFIER TOKEN H_NS N CSV VR [VR ...]\n");
        return 2;
    }
    const char *dir = argv[1], *model = argv[2], *token = argv[3];
    const long long h_ns = atoll(argv[4]);
    const long n = atol(argv[5]);
    const int nvr = argc - 7;
    fmi3ValueReference *vr = calloc((size_t)nvr, sizeof *vr);
    double *values = calloc((size_t)nvr, sizeof *values);
    char *path = malloc(strlen(dir) + strlen(model) + 64);
    char *resources = malloc(strlen(dir) + 16);
    if (!vr || !values || !path || !resources || h_ns <= 0 || n <= 0) return 2;
    for (int i = 0; i < nvr; ++i) vr[i] = (fmi3ValueReference)strtoul(argv[7 + i], NULL, 10);
    sprintf(path, "%s/binaries/x86_64-linux/%s.so", dir, model);
    sprintf(resources, "%s/resources/", dir);
    void *lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        fprintf(stderr, "host3: %s\n", dlerror());
        return 1;
    }
    InstantiateCS instantiate = (InstantiateCS)symbol(lib, "fmi3InstantiateCoSimulation");
    EnterInit enter = (EnterInit)symbol(lib, "fmi3EnterInitializationMode");
    Plain exit_init = (Plain)symbol(lib, "fmi3ExitInitializationMode");
    Plain terminate = (Plain)symbol(lib, "fmi3Terminate");
    DoStep step = (DoStep)symbol(lib, "fmi3DoStep");
    GetFloat64 get = (GetFloat64)symbol(lib, "fmi3GetFloat64");
    FreeInstance free_instance = (FreeInstance)symbol(lib, "fmi3FreeInstance");
    if (!instantiate || !enter || !exit_init || !terminate || !step || !get || !free_instance)
        return 1;
    fmi3Instance fmu = instantiate("host3", token, resources, false, false, false, false, NULL, 0,
                                   NULL, logger, NULL);
    if (!fmu) {
        fprintf(stderr, "host3: fmi3InstantiateCoSimulation returned NULL\n");
        return 1;
    }
    FILE *csv = fopen(argv[6], "w");
    if (!csv) return 2;
    int failed = enter(fmu, false, 0.0, 0.0, false, 0.0) > fmi3Warning ||
                 exit_init(fmu) > fmi3Warning;
    for (long k = 0; k < n && !failed; ++k) {
        const double t = (double)(k * h_ns) / 1e9, h = (double)((k + 1) * h_ns) / 1e9 - t;
        bool event, stop, early;
        double last;
        failed = step(fmu, t, h, true, &event, &stop, &early, &last) > fmi3Warning ||
                 get(fmu, vr, (size_t)nvr, values, (size_t)nvr) > fmi3Warning;
        fprintf(csv, "%.17g", t + h);
        for (int i = 0; i < nvr && !failed; ++i) fprintf(csv, ",%.17g", values[i]);
        fputc('\n', csv);
    }
    if (!failed) failed = terminate(fmu) > fmi3Warning;
    free_instance(fmu);
    fclose(csv);
    free(vr), free(values), free(path), free(resources);
    return failed ? 1 : 0;
}
