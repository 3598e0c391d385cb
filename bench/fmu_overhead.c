/*
 * fmu_overhead.c -- what the FMUs' front layer adds per fmi2DoStep (bench/fmu_startup.py).
 *
 * Usage: fmu_overhead UNZIPDIR MODELIDENTIFIER GUID BLOCKS STEPS
 *
 * Two instances of the same FMU in one process: A through the front layer
 * (binaries/linux64/<id>.so), B through pythonfmu's library directly (<id>_pythonfmu.so, the
 * library the layer forwards to). Blocks of STEPS fmi2DoStep calls alternate between A and B;
 * each block's mean time per call (ns) is printed as "layer NS" or "direct NS". B is created the
 * way the layer creates its instances (the Python side prepared by A, and the reference
 * pythonfmu 0.7.0 drops on the entry module's dictionary lent beforehand, see
 * fmu_src/fmi_front/runtime.c).
 */
#define _GNU_SOURCE
#include <string.h>
#include <time.h>

#include "../tests/c_host/fmi2_api.h"

static void logger(void *env, const char *name, int status, const char *cat, const char *msg, ...)
{
    (void)env, (void)cat;
    if (status >= 2) fprintf(stderr, "[%d] %s: %s\n", status, name, msg);
}

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e9 + ts.tv_nsec;
}

static void start(const Api *a, fmi2Component c)
{
    if (!c || a->setup(c, 0, 0.0, 0.0, 0, 0.0) || a->enter(c) || a->exit_(c)) {
        fprintf(stderr, "initialization failed\n");
        exit(1);
    }
}

int main(int argc, char **argv)
{
    if (argc != 6) {
        fprintf(stderr, "usage: %s UNZIPDIR MODELIDENTIFIER GUID BLOCKS STEPS\n", argv[0]);
        return 2;
    }
    const char *dir = argv[1], *id = argv[2], *guid = argv[3];
    const int blocks = atoi(argv[4]), steps = atoi(argv[5]);
    char path[4096], uri[4200], entry[256];
    const Api la = load_api(dir, id, "");
    static const Callbacks cb = {logger, calloc, free, NULL, NULL};
    snprintf(uri, sizeof uri, "file://%s/resources", dir);
    fmi2Component a = la.instantiate("layer", 1, guid, uri, &cb, 0, 0); /* starts Python */
    start(&la, a);
    /* loaded by the layer already (after libpython): the same library */
    const Api da = load_api(dir, id, "_pythonfmu");
    /* B: pythonfmu's library directly, prepared as the layer prepares its instances */
    snprintf(path, sizeof path, "%s/resources/slavemodule.txt", dir);
    FILE *fp = fopen(path, "r");
    if (!fp || !fgets(entry, sizeof entry, fp)) return 2;
    fclose(fp);
    entry[strcspn(entry, "\r\n")] = '\0';
    int (*ensure)(void) = (int (*)(void))need(RTLD_DEFAULT, "PyGILState_Ensure");
    void (*release)(int) = (void (*)(int))need(RTLD_DEFAULT, "PyGILState_Release");
    void *(*import)(const char *) = (void *(*)(const char *))need(RTLD_DEFAULT,
                                                                   "PyImport_ImportModule");
    void *(*getdict)(void *) = (void *(*)(void *))need(RTLD_DEFAULT, "PyModule_GetDict");
    void (*incref)(void *) = (void (*)(void *))need(RTLD_DEFAULT, "Py_IncRef");
    const int gil = ensure();
    void *module = import(entry);
    if (!module) return 2;
    incref(getdict(module));
    release(gil);
    fmi2Component b = da.instantiate("direct", 1, guid, uri, &cb, 0, 0);
    start(&da, b);

    const double h = 1e-3;
    long ka = 0, kb = 0;
    for (int i = 0; i < blocks; ++i) {
        double t0 = now();
        for (int k = 0; k < steps; ++k, ++ka)
            if (la.step(a, ka * h, h, 1) != 0) return 1;
        double t1 = now();
        for (int k = 0; k < steps; ++k, ++kb)
            if (da.step(b, kb * h, h, 1) != 0) return 1;
        double t2 = now();
        printf("layer %.1f\ndirect %.1f\n", (t1 - t0) / steps, (t2 - t1) / steps);
    }
    la.terminate(a);
    da.terminate(b);
    la.free_(a);
    da.free_(b);
    return 0;
}
