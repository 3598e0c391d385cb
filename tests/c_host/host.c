/*
 * host.c -- a minimal FMI 2.0 co-simulation master in plain C.
 *
 * Loads the linux64 binaries of unpacked FMI 2.0 co-simulation FMUs with dlopen(), couples their
 * real-valued outputs and inputs with a fixed macro step and writes the recorded outputs as CSV.
 * It is the "non-Python host" of the drillstring project's FMU tests (tests/test_fmu_cosim.py) and
 * the example of README.md, "Using the FMUs in other tools".
 *
 * The exchange follows libcosim's fixed_step_algorithm (Jacobi), so that the results can be compared
 * with libcosim bit for bit:
 *   initialization: set start values, fmi2SetupExperiment, fmi2EnterInitializationMode, read the
 *     connected outputs; then N times (N = number of FMUs): write pending inputs, read outputs,
 *     transfer outputs to pending inputs; then write pending inputs, fmi2ExitInitializationMode,
 *     read outputs, transfer;
 *   macro step k (t_k = k*H_ns/1e9 s, h_k = t_{k+1} - t_k, H_ns the step in integer nanoseconds):
 *     for every FMU: write pending inputs, fmi2DoStep(t_k, h_k), read outputs; then transfer.
 *
 * The resource location passed to fmi2Instantiate is a proper RFC 3986 file URI: every byte of the
 * folder's path other than unreserved characters and '/' is percent-encoded.
 *
 * Usage: host CONFIG_FILE. Exit status 0 on success, 1 if an FMU call fails (the FMU's log says
 * why), 2 on a usage or configuration error. The configuration is one directive per line (a line
 * starting with '#' is a comment); paths are the rest of their line and may contain spaces:
 *   fmu NAME MODELIDENTIFIER GUID UNZIPDIR
 *   real NAME VR VALUE | integer NAME VR VALUE | boolean NAME VR 0|1   start/parameter values
 *   connect SRCNAME SRCVR DSTNAME DSTVR real output -> real input
 *   record NAME VR COLUMN               a real variable written to the CSV after every macro step
 *   step_ns H_NS                        macro step in nanoseconds (libcosim's time base)
 *   steps N                             number of macro steps
 *   csv PATH                            output file
 *   logging 0|1                         loggingOn of fmi2Instantiate (default 1)
 *   unload 0|1                          dlclose() the FMU binaries before exit (default 1)
 *   timing 0|1                          print the wall time of the macro steps to stderr
 *                                       ("host: N macro steps in S s"; default 0)
 *   libpython PATH                      optional: dlopen() PATH with RTLD_GLOBAL before the FMUs
 *                                       (the drillstring FMUs do not need it: they load libpython
 *                                       themselves and then use the one found here)
 */
#define _POSIX_C_SOURCE 200809L
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* ---- FMI 2.0 types (fmi2TypesPlatform.h, fmi2FunctionTypes.h of the standard) ---------------- */
typedef void *fmi2Component;
typedef void *fmi2ComponentEnvironment;
typedef unsigned int fmi2ValueReference;
typedef double fmi2Real;
typedef int fmi2Integer;
typedef int fmi2Boolean;
typedef const char *fmi2String;
typedef enum { fmi2OK, fmi2Warning, fmi2Discard, fmi2Error, fmi2Fatal, fmi2Pending } fmi2Status;
typedef enum { fmi2ModelExchange, fmi2CoSimulation } fmi2Type;
typedef void (*fmi2CallbackLogger)(fmi2ComponentEnvironment, fmi2String, fmi2Status, fmi2String,
                                   fmi2String, ...);
typedef void *(*fmi2CallbackAllocateMemory)(size_t, size_t);
typedef void (*fmi2CallbackFreeMemory)(void *);
typedef void (*fmi2StepFinished)(fmi2ComponentEnvironment, fmi2Status);
typedef struct {
    fmi2CallbackLogger logger;
    fmi2CallbackAllocateMemory allocateMemory;
    fmi2CallbackFreeMemory freeMemory;
    fmi2StepFinished stepFinished;
    fmi2ComponentEnvironment componentEnvironment;
} fmi2CallbackFunctions;

typedef fmi2Component (*Instantiate_t)(fmi2String, fmi2Type, fmi2String, fmi2String,
                                       const fmi2CallbackFunctions *, fmi2Boolean, fmi2Boolean);
typedef void (*FreeInstance_t)(fmi2Component);
typedef fmi2Status (*SetupExperiment_t)(fmi2Component, fmi2Boolean, fmi2Real, fmi2Real, fmi2Boolean,
                                        fmi2Real);
typedef fmi2Status (*Component_t)(fmi2Component);
typedef fmi2Status (*GetReal_t)(fmi2Component, const fmi2ValueReference *, size_t, fmi2Real *);
typedef fmi2Status (*SetReal_t)(fmi2Component, const fmi2ValueReference *, size_t, const fmi2Real *);
typedef fmi2Status (*SetInteger_t)(fmi2Component, const fmi2ValueReference *, size_t,
                                   const fmi2Integer *);
typedef fmi2Status (*SetBoolean_t)(fmi2Component, const fmi2ValueReference *, size_t,
                                   const fmi2Boolean *);
typedef fmi2Status (*DoStep_t)(fmi2Component, fmi2Real, fmi2Real, fmi2Boolean);
typedef fmi2Status (*GetRealStatus_t)(fmi2Component, int, fmi2Real *);

/* ---- host data ------------------------------------------------------------------------------- */
#define MAX_FMUS 8
#define MAX_ITEMS 64
#define MAX_TOKEN 4096

typedef struct {
    char name[MAX_TOKEN];
    char dir[MAX_TOKEN];
    char id[MAX_TOKEN];
    char guid[MAX_TOKEN];
    void *lib;
    fmi2Component c;
    Instantiate_t instantiate;
    FreeInstance_t free_instance;
    SetupExperiment_t setup_experiment;
    Component_t enter_init, exit_init, terminate;
    GetReal_t get_real;
    SetReal_t set_real;
    SetInteger_t set_integer;
    SetBoolean_t set_boolean;
    DoStep_t do_step;
    GetRealStatus_t get_real_status;
} Fmu;

typedef struct { int fmu; char kind; fmi2ValueReference vr; double value; } Start;
typedef struct { int src, dst; fmi2ValueReference src_vr, dst_vr; double cache, pending; int has; } Link;
typedef struct { int fmu; fmi2ValueReference vr; char column[MAX_TOKEN]; } Record;

static Fmu fmus[MAX_FMUS];
static Start starts[MAX_ITEMS];
static Link links[MAX_ITEMS];
static Record records[MAX_ITEMS];
static int n_fmus, n_starts, n_links, n_records;
static long long step_ns = 0, n_steps = 0;
static int unload = 1, logging = 1, timing = 0;
static char libpython[MAX_TOKEN], csv_path[MAX_TOKEN];

static void logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                   fmi2String category, fmi2String message, ...)
{
    static const char *names[] = {"OK", "Warning", "Discard", "Error", "Fatal", "Pending"};
    va_list args;
    (void)env;
    fprintf(stderr, "[%s] %s (%s): ", (status >= 0 && status <= 5) ? names[status] : "?",
            instance ? instance : "?", category ? category : "");
    va_start(args, message);
    vfprintf(stderr, message, args);
    va_end(args);
    fputc('\n', stderr);
}

static int find_fmu(const char *name)
{
    for (int i = 0; i < n_fmus; ++i)
        if (strcmp(fmus[i].name, name) == 0) return i;
    fprintf(stderr, "host: unknown FMU name '%s'\n", name);
    exit(2);
}

static void *sym(Fmu *f, const char *name)
{
    void *p = dlsym(f->lib, name);
    if (!p) {
        fprintf(stderr, "host: %s lacks %s: %s\n", f->name, name, dlerror());
        exit(2);
    }
    return p;
}

static void check(fmi2Status s, const Fmu *f, const char *what)
{
    if (s != fmi2OK && s != fmi2Warning) {
        fprintf(stderr, "host: %s failed for %s with status %d\n", what, f->name, (int)s);
        exit(1);
    }
}

/* the rest of the line after n blank-separated words, without the newline */
static const char *rest(const char *line, int n)
{
    const char *p = line;
    for (int i = 0; i < n; ++i) {
        p += strspn(p, " \t");
        p += strcspn(p, " \t\n");
    }
    return p + strspn(p, " \t");
}

static void copy_rest(char *out, size_t n, const char *line, int words)
{
    snprintf(out, n, "%s", rest(line, words));
    out[strcspn(out, "\r\n")] = '\0';
}

static void read_config(const char *path)
{
    char line[3 * MAX_TOKEN], a[MAX_TOKEN], b[MAX_TOKEN], c[MAX_TOKEN], d[MAX_TOKEN], e[MAX_TOKEN];
    FILE *fp = fopen(path, "r");
    if (!fp) {
        fprintf(stderr, "host: cannot open config %s\n", path);
        exit(2);
    }
    while (fgets(line, sizeof line, fp)) {
        if (line[strspn(line, " \t")] == '#') continue;
        int n = sscanf(line, "%4095s %4095s %4095s %4095s %4095s", a, b, c, d, e);
        if (n <= 0) continue;
        if (strcmp(a, "libpython") == 0 && n >= 2) {
            copy_rest(libpython, sizeof libpython, line, 1);
        } else if (strcmp(a, "fmu") == 0 && n == 5 && n_fmus < MAX_FMUS) {
            Fmu *f = &fmus[n_fmus++];
            snprintf(f->name, sizeof f->name, "%s", b);
            snprintf(f->id, sizeof f->id, "%s", c);
            snprintf(f->guid, sizeof f->guid, "%s", d);
            copy_rest(f->dir, sizeof f->dir, line, 4);
        } else if ((strcmp(a, "real") == 0 || strcmp(a, "integer") == 0 ||
                    strcmp(a, "boolean") == 0) && n == 4 && n_starts < MAX_ITEMS) {
            Start *s = &starts[n_starts++];
            s->fmu = find_fmu(b);
            s->kind = a[0];
            s->vr = (fmi2ValueReference)strtoul(c, NULL, 10);
            s->value = strtod(d, NULL);
        } else if (strcmp(a, "connect") == 0 && n == 5 && n_links < MAX_ITEMS) {
            Link *l = &links[n_links++];
            l->src = find_fmu(b);
            l->src_vr = (fmi2ValueReference)strtoul(c, NULL, 10);
            l->dst = find_fmu(d);
            l->dst_vr = (fmi2ValueReference)strtoul(e, NULL, 10);
        } else if (strcmp(a, "record") == 0 && n == 4 && n_records < MAX_ITEMS) {
            Record *r = &records[n_records++];
            r->fmu = find_fmu(b);
            r->vr = (fmi2ValueReference)strtoul(c, NULL, 10);
            snprintf(r->column, sizeof r->column, "%s", d);
        } else if (strcmp(a, "step_ns") == 0 && n == 2) {
            step_ns = strtoll(b, NULL, 10);
        } else if (strcmp(a, "steps") == 0 && n == 2) {
            n_steps = strtoll(b, NULL, 10);
        } else if (strcmp(a, "csv") == 0 && n >= 2) {
            copy_rest(csv_path, sizeof csv_path, line, 1);
        } else if (strcmp(a, "unload") == 0 && n == 2) {
            unload = atoi(b);
        } else if (strcmp(a, "timing") == 0 && n == 2) {
            timing = atoi(b);
        } else if (strcmp(a, "logging") == 0 && n == 2) {
            logging = atoi(b);
        } else {
            fprintf(stderr, "host: bad config line: %s", line);
            exit(2);
        }
    }
    fclose(fp);
    if (n_fmus == 0 || step_ns <= 0 || n_steps <= 0 || csv_path[0] == '\0') {
        fprintf(stderr, "host: config needs fmu, step_ns > 0, steps > 0 and csv\n");
        exit(2);
    }
}

/* "file://" + the percent-encoded absolute path (RFC 3986: unreserved characters and '/' stay) */
static void file_uri(char *out, size_t n, const char *path)
{
    static const char hex[] = "0123456789ABCDEF";
    size_t k = (size_t)snprintf(out, n, "file://");
    for (const unsigned char *p = (const unsigned char *)path; *p && k + 4 < n; ++p) {
        if ((*p >= 'A' && *p <= 'Z') || (*p >= 'a' && *p <= 'z') || (*p >= '0' && *p <= '9') ||
            strchr("-._~/", *p)) {
            out[k++] = (char)*p;
        } else {
            out[k++] = '%';
            out[k++] = hex[*p >> 4];
            out[k++] = hex[*p & 15];
        }
    }
    out[k] = '\0';
}

static void load(Fmu *f)
{
    char path[3 * MAX_TOKEN], uri[9 * MAX_TOKEN];
    snprintf(path, sizeof path, "%s/binaries/linux64/%s.so", f->dir, f->id);
    f->lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!f->lib) {
        fprintf(stderr, "host: cannot load %s: %s\n", path, dlerror());
        exit(2);
    }
    f->instantiate = (Instantiate_t)sym(f, "fmi2Instantiate");
    f->free_instance = (FreeInstance_t)sym(f, "fmi2FreeInstance");
    f->setup_experiment = (SetupExperiment_t)sym(f, "fmi2SetupExperiment");
    f->enter_init = (Component_t)sym(f, "fmi2EnterInitializationMode");
    f->exit_init = (Component_t)sym(f, "fmi2ExitInitializationMode");
    f->terminate = (Component_t)sym(f, "fmi2Terminate");
    f->get_real = (GetReal_t)sym(f, "fmi2GetReal");
    f->set_real = (SetReal_t)sym(f, "fmi2SetReal");
    f->set_integer = (SetInteger_t)sym(f, "fmi2SetInteger");
    f->set_boolean = (SetBoolean_t)sym(f, "fmi2SetBoolean");
    f->do_step = (DoStep_t)sym(f, "fmi2DoStep");
    f->get_real_status = (GetRealStatus_t)sym(f, "fmi2GetRealStatus");

    static const fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};
    char resources[3 * MAX_TOKEN];
    snprintf(resources, sizeof resources, "%s/resources", f->dir);
    file_uri(uri, sizeof uri, resources);
    f->c = f->instantiate(f->name, fmi2CoSimulation, f->guid, uri, &callbacks, 0, logging);
    if (!f->c) {
        fprintf(stderr, "host: fmi2Instantiate failed for %s\n", f->name);
        exit(1);
    }
}

/* write the pending inputs of FMU i (libcosim: slave_simulator::set_variables) */
static void set_inputs(int i)
{
    for (int k = 0; k < n_links; ++k) {
        if (links[k].dst != i || !links[k].has) continue;
        check(fmus[i].set_real(fmus[i].c, &links[k].dst_vr, 1, &links[k].pending), &fmus[i],
              "fmi2SetReal");
    }
}

/* read the connected outputs of FMU i (libcosim: slave_simulator::get_variables) */
static void get_outputs(int i)
{
    for (int k = 0; k < n_links; ++k) {
        if (links[k].src != i) continue;
        check(fmus[i].get_real(fmus[i].c, &links[k].src_vr, 1, &links[k].cache), &fmus[i],
              "fmi2GetReal");
    }
}

/* libcosim: fixed_step_algorithm::calculate_and_transfer */
static void transfer(void)
{
    for (int k = 0; k < n_links; ++k) {
        links[k].pending = links[k].cache;
        links[k].has = 1;
    }
}

static void write_row(FILE *out, double t)
{
    fprintf(out, "%.17g", t);
    for (int k = 0; k < n_records; ++k) {
        Fmu *f = &fmus[records[k].fmu];
        double v;
        check(f->get_real(f->c, &records[k].vr, 1, &v), f, "fmi2GetReal");
        fprintf(out, ",%.17g", v);
    }
    fputc('\n', out);
}

int main(int argc, char **argv)
{
    if (argc != 2) {
        fprintf(stderr, "usage: %s CONFIG_FILE\n", argv[0]);
        return 2;
    }
    read_config(argv[1]);

    void *py = NULL;
    if (libpython[0]) {
        /* pythonfmu's export library is not linked to libpython, and the Python extension
           modules it imports (numpy) expect the Python C API in the global namespace. */
        py = dlopen(libpython, RTLD_NOW | RTLD_GLOBAL);
        if (!py) {
            fprintf(stderr, "host: cannot load %s: %s\n", libpython, dlerror());
            return 2;
        }
    }
    for (int i = 0; i < n_fmus; ++i) load(&fmus[i]);

    for (int k = 0; k < n_starts; ++k) {
        Fmu *f = &fmus[starts[k].fmu];
        if (starts[k].kind == 'r') {
            check(f->set_real(f->c, &starts[k].vr, 1, &starts[k].value), f, "fmi2SetReal");
        } else if (starts[k].kind == 'i') {
            fmi2Integer v = (fmi2Integer)starts[k].value;
            check(f->set_integer(f->c, &starts[k].vr, 1, &v), f, "fmi2SetInteger");
        } else {
            fmi2Boolean v = starts[k].value != 0.0;
            check(f->set_boolean(f->c, &starts[k].vr, 1, &v), f, "fmi2SetBoolean");
        }
    }

    for (int i = 0; i < n_fmus; ++i) {
        check(fmus[i].setup_experiment(fmus[i].c, 0, 0.0, 0.0, 0, 0.0), &fmus[i],
              "fmi2SetupExperiment");
        check(fmus[i].enter_init(fmus[i].c), &fmus[i], "fmi2EnterInitializationMode");
        get_outputs(i);
    }
    for (int it = 0; it < n_fmus; ++it) {
        for (int i = 0; i < n_fmus; ++i) {
            set_inputs(i);
            get_outputs(i);
        }
        transfer();
    }
    for (int i = 0; i < n_fmus; ++i) {
        set_inputs(i);
        check(fmus[i].exit_init(fmus[i].c), &fmus[i], "fmi2ExitInitializationMode");
        get_outputs(i);
    }
    transfer();

    FILE *out = fopen(csv_path, "w");
    if (!out) {
        fprintf(stderr, "host: cannot write %s\n", csv_path);
        return 2;
    }
    fprintf(out, "\"time\"");
    for (int k = 0; k < n_records; ++k) fprintf(out, ",\"%s\"", records[k].column);
    fputc('\n', out);
    write_row(out, 0.0);

    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    for (long long k = 0; k < n_steps; ++k) {
        const double t = (double)(k * step_ns) / 1e9;
        const double h = (double)((k + 1) * step_ns) / 1e9 - t;
        for (int i = 0; i < n_fmus; ++i) {
            set_inputs(i);
            const fmi2Status s = fmus[i].do_step(fmus[i].c, t, h, 1);
            if (s == fmi2Discard) {
                double reached = t;
                fmus[i].get_real_status(fmus[i].c, 2 /* fmi2LastSuccessfulTime */, &reached);
                fprintf(stderr, "host: fmi2DoStep(%.17g, %.17g) of %s returned fmi2Discard; "
                        "fmi2LastSuccessfulTime = %.17g\n", t, h, fmus[i].name, reached);
                fclose(out);
                return 1;
            }
            check(s, &fmus[i], "fmi2DoStep");
            get_outputs(i);
        }
        transfer();
        write_row(out, t + h);
    }
    clock_gettime(CLOCK_MONOTONIC, &t1);
    if (timing) {
        fprintf(stderr, "host: %lld macro steps in %.9f s\n", n_steps,
                (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec));
    }
    if (fclose(out) != 0) {
        fprintf(stderr, "host: error writing %s\n", csv_path);
        return 2;
    }

    for (int i = 0; i < n_fmus; ++i) check(fmus[i].terminate(fmus[i].c), &fmus[i], "fmi2Terminate");
    for (int i = 0; i < n_fmus; ++i) fmus[i].free_instance(fmus[i].c);
    if (unload) {
        for (int i = n_fmus - 1; i >= 0; --i) dlclose(fmus[i].lib);
    }
    (void)py;
    return 0;
}
