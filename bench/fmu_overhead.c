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
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

typedef void *fmi2Component;
typedef int fmi2Status;
typedef void (*Logger)(void *, const char *, int, const char *, const char *, ...);
typedef struct {
    Logger logger;
    void *(*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void *);
    void *stepFinished;
    void *componentEnvironment;
} Callbacks;
typedef fmi2Component (*Instantiate_t)(const char *, int, const char *, const char *,
                                       const Callbacks *, int, int);
typedef fmi2Status (*Setup_t)(fmi2Component, int, double, double, int, double);
typedef fmi2Status (*Component_t)(fmi2Component);
typedef fmi2Status (*DoStep_t)(fmi2Component, double, double, int);
typedef void (*Free_t)(fmi2Component);

typedef struct {
    Instantiate_t instantiate;
    Setup_t setup;
    Component_t enter, exit_, terminate;
    DoStep_t step;
    Free_t free_;
} Api;

static void logger(void *env, const char *name, int status, const char *cat, const char *msg, ...)
{
    (void)env, (void)cat;
    if (status >= 2) fprintf(stderr, "[%d] %s: %s\n", status, name, msg);
}

static void *need(void *lib, const char *name)
{
    void *p = dlsym(lib, name);
    if (!p) {
        fprintf(stderr, "missing %s: %s\n", name, dlerror());
        exit(2);
    }
    return p;
}

static Api api(void *lib)
{
    Api a;
    a.instantiate = (Instantiate_t)need(lib, "fmi2Instantiate");
    a.setup = (Setup_t)need(lib, "fmi2SetupExperiment");
    a.enter = (Component_t)need(lib, "fmi2EnterInitializationMode");
    a.exit_ = (Component_t)need(lib, "fmi2ExitInitializationMode");
    a.terminate = (Component_t)need(lib, "fmi2Terminate");
    a.step = (DoStep_t)need(lib, "fmi2DoStep");
    a.free_ = (Free_t)need(lib, "fmi2FreeInstance");
    return a;
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
    snprintf(path, sizeof path, "%s/binaries/linux64/%s.so", dir, id);
    void *layer = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!layer) {
        fprintf(stderr, "cannot load: %s\n", dlerror());
        return 2;
    }
    const Api la = api(layer);
    static const Callbacks cb = {logger, calloc, free, NULL, NULL};
    snprintf(uri, sizeof uri, "file://%s/resources", dir);
    fmi2Component a = la.instantiate("layer", 1, guid, uri, &cb, 0, 0); /* starts Python */
    start(&la, a);
    /* loaded by the layer already (after libpython): the same library */
    snprintf(path, sizeof path, "%s/binaries/linux64/%s_pythonfmu.so", dir, id);
    void *direct = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!direct) {
        fprintf(stderr, "cannot load: %s\n", dlerror());
        return 2;
    }
    const Api da = api(direct);

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
