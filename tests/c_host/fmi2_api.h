/*
 * fmi2_api.h -- what the small plain C hosts share (tests/c_host/cycles.c, tests/c_host/sigint.c,
 * bench/fmu_overhead.c): the few FMI 2.0 types they use and the FMU's functions they call, looked
 * up in one of its shared libraries. (tests/c_host/host.c declares the whole standard's types.)
 */
#ifndef DRILLSTRING_TESTS_FMI2_API_H
#define DRILLSTRING_TESTS_FMI2_API_H

#include <dlfcn.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>

typedef void *fmi2Component;
typedef void *fmi2FMUstate;
typedef unsigned int fmi2ValueReference;
typedef int fmi2Status;
typedef void (*Logger)(void *, const char *, int, const char *, const char *, ...);
typedef struct {
    Logger logger;
    void *(*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void *);
    void *stepFinished;
    void *componentEnvironment;
} Callbacks;

typedef struct {
    fmi2Component (*instantiate)(const char *, int, const char *, const char *, const Callbacks *,
                                 int, int);
    fmi2Status (*setup)(fmi2Component, int, double, double, int, double);
    fmi2Status (*enter)(fmi2Component);
    fmi2Status (*exit_)(fmi2Component);
    fmi2Status (*terminate)(fmi2Component);
    fmi2Status (*step)(fmi2Component, double, double, int);
    fmi2Status (*get_real)(fmi2Component, const fmi2ValueReference *, size_t, double *);
    fmi2Status (*get_state)(fmi2Component, fmi2FMUstate *);
    void (*free_)(fmi2Component);
} Api;

/* The symbol ``name`` of ``lib`` (RTLD_DEFAULT: of the process); exit status 2 if missing. */
static inline void *need(void *lib, const char *name)
{
    void *p = dlsym(lib, name);
    if (!p) {
        fprintf(stderr, "missing %s: %s\n", name, dlerror());
        exit(2);
    }
    return p;
}

/* The FMU's functions in DIR/binaries/linux64/MODEL SUFFIX.so (SUFFIX "": the FMU's own library);
 * exit status 2 if the library or one of them is missing. */
static inline Api load_api(const char *dir, const char *model, const char *suffix)
{
    char path[PATH_MAX + 64];
    snprintf(path, sizeof path, "%s/binaries/linux64/%s%s.so", dir, model, suffix);
    void *lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        fprintf(stderr, "cannot load: %s\n", dlerror());
        exit(2);
    }
    Api a;
    a.instantiate = need(lib, "fmi2Instantiate");
    a.setup = need(lib, "fmi2SetupExperiment");
    a.enter = need(lib, "fmi2EnterInitializationMode");
    a.exit_ = need(lib, "fmi2ExitInitializationMode");
    a.terminate = need(lib, "fmi2Terminate");
    a.step = need(lib, "fmi2DoStep");
    a.get_real = need(lib, "fmi2GetReal");
    a.get_state = need(lib, "fmi2GetFMUstate");
    a.free_ = need(lib, "fmi2FreeInstance");
    return a;
}

#endif
