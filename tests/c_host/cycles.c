/*
 * cycles.c -- instances made and freed in one process, from a thread with a given stack size.
 *
 * A plain C host (no Python in the process until the FMU starts it) for the front layer's promises
 * about the process it lives in (tests/test_fmu_lifecycle.py):
 *
 *  - nothing per instance: N cycles of fmi2Instantiate, fmi2SetupExperiment,
 *    fmi2Enter/ExitInitializationMode, fmi2DoStep, fmi2GetReal, an FMU state taken and left to
 *    fmi2FreeInstance (which must free it), fmi2FreeInstance; the resident memory is printed after
 *    WARMUP cycles and after the last one;
 *  - a host worker thread with a small stack: every FMI call runs in a pthread created with
 *    STACK_KIB KiB of stack (the main thread only waits), so a frame too large for it is a
 *    SIGSEGV, not a pass.
 *
 * Usage: cycles UNZIPDIR MODELIDENTIFIER GUID CYCLES WARMUP LOGGING STACK_KIB VR STATE
 *   VR: value reference of a Real output read after each step; STATE 1: an FMU state is taken
 *   after the step and left to fmi2FreeInstance, 0: none.
 * Prints "rss WARMUP BYTES" and "rss CYCLES BYTES" (resident set size from /proc/self/statm) and
 * "messages N" (log messages received); exit status 0, or 1 with the failing call on stderr.
 */
#define _GNU_SOURCE
#include <pthread.h>
#include <string.h>
#include <unistd.h>

#include "fmi2_api.h"

static Api api;
static const char *dir, *model, *guid;
static long cycles, warmup, messages;
static int logging, take_state;
static fmi2ValueReference out_vr;
static char uri[3 * PATH_MAX + 16];
static int failed;

static void logger(void *env, const char *name, int status, const char *cat, const char *msg, ...)
{
    (void)env, (void)cat;
    ++messages;
    if (status >= 2) fprintf(stderr, "[%d] %s: %s\n", status, name, msg);
}

static long rss(void)
{
    long pages = 0, resident = 0;
    FILE *f = fopen("/proc/self/statm", "r");
    if (!f || fscanf(f, "%ld %ld", &pages, &resident) != 2) resident = -1;
    if (f) fclose(f);
    return resident * sysconf(_SC_PAGESIZE);
}

#define CHECK(call, what)                                                                          \
    if ((call) > 1) {                                                                              \
        fprintf(stderr, "cycles: %s failed in cycle %ld\n", what, k);                              \
        failed = 1;                                                                                \
        return NULL;                                                                               \
    }

static void *run(void *unused)
{
    (void)unused;
    static const Callbacks callbacks = {logger, calloc, free, NULL, NULL};
    for (long k = 0; k < cycles; ++k) {
        fmi2Component c = api.instantiate("cycle", 1, guid, uri, &callbacks, 0, logging);
        if (!c) {
            fprintf(stderr, "cycles: fmi2Instantiate failed in cycle %ld\n", k);
            failed = 1;
            return NULL;
        }
        double y = 0.0;
        fmi2FMUstate state = NULL;
        CHECK(api.setup(c, 0, 0.0, 0.0, 0, 0.0), "fmi2SetupExperiment")
        CHECK(api.enter(c), "fmi2EnterInitializationMode")
        CHECK(api.exit_(c), "fmi2ExitInitializationMode")
        CHECK(api.step(c, 0.0, 0.01, 1), "fmi2DoStep")
        CHECK(api.get_real(c, &out_vr, 1, &y), "fmi2GetReal")
        if (take_state) CHECK(api.get_state(c, &state), "fmi2GetFMUstate") /* freed with c */
        api.free_(c);
        if (k + 1 == warmup) printf("rss %ld %ld\n", k + 1, rss());
    }
    printf("rss %ld %ld\nmessages %ld\n", cycles, rss(), messages);
    return NULL;
}

int main(int argc, char **argv)
{
    if (argc != 10) {
        fprintf(stderr, "usage: cycles UNZIPDIR MODELIDENTIFIER GUID CYCLES WARMUP LOGGING "
                        "STACK_KIB VR STATE\n");
        return 2;
    }
    dir = argv[1], model = argv[2], guid = argv[3];
    cycles = atol(argv[4]), warmup = atol(argv[5]), logging = atoi(argv[6]);
    const long stack_kib = atol(argv[7]);
    out_vr = (fmi2ValueReference)strtoul(argv[8], NULL, 10);
    take_state = atoi(argv[9]);
    api = load_api(dir, model, "");
    /* "file://" + the percent-encoded absolute path of the resources folder */
    static const char hex[] = "0123456789ABCDEF";
    char resources[PATH_MAX + 16];
    snprintf(resources, sizeof resources, "%s/resources", dir);
    size_t n = (size_t)snprintf(uri, sizeof uri, "file://");
    for (const unsigned char *p = (const unsigned char *)resources; *p; ++p) {
        if ((*p >= 'A' && *p <= 'Z') || (*p >= 'a' && *p <= 'z') || (*p >= '0' && *p <= '9') ||
            strchr("-._~/", *p)) {
            uri[n++] = (char)*p;
        } else {
            uri[n++] = '%', uri[n++] = hex[*p >> 4], uri[n++] = hex[*p & 15];
        }
    }
    uri[n] = '\0';
    pthread_attr_t attr;
    pthread_t thread;
    pthread_attr_init(&attr);
    if (pthread_attr_setstacksize(&attr, (size_t)stack_kib * 1024) != 0) {
        fprintf(stderr, "cycles: stack size %ld KiB refused\n", stack_kib);
        return 2;
    }
    if (pthread_create(&thread, &attr, run, NULL) != 0) {
        fprintf(stderr, "cycles: cannot create the thread\n");
        return 2;
    }
    pthread_join(thread, NULL);
    fflush(stdout);
    return failed;
}
