/*
 * sigint.c -- a plain C host's signal dispositions survive the FMU's Python.
 *
 * The FMU starts Python in the host's process; that interpreter must leave the host's handling
 * of SIGINT (Ctrl-C) as it was: CPython 3.11 installs its own SIGINT handler when its `signal`
 * module is first imported, whatever the interpreter's configuration says, after which Ctrl-C
 * only sets a flag nobody reads and the host runs on.
 *
 * Usage: sigint UNZIPDIR MODELIDENTIFIER GUID VR MODE
 *   VR: a Real output read after each step. MODE "handler": the host installs its own SIGINT
 *   handler before fmi2Instantiate; "default": it sets SIG_DFL (what it inherited is not trusted:
 *   a parent that ignores SIGINT, as a pytest worker was seen to, passes SIG_IGN on to its
 *   children). The host makes an instance, initializes it, makes 10 steps and reads VR, then
 *   prints "before X" and "after X" (X: the SIGINT disposition, "default", "ignore", "host" or
 *   "other") and raises SIGINT: with "default"
 *   the process ends by the signal, with "handler" the host's handler prints "host handler ran"
 *   and the host exits 0. "survived" printed after the raise means the signal was swallowed.
 */
#define _GNU_SOURCE
#include <signal.h>
#include <string.h>

#include "fmi2_api.h"

static void logger(void *env, const char *instance, int status, const char *category,
                   const char *message, ...)
{
    (void)env, (void)instance, (void)category;
    if (status > 1) fprintf(stderr, "sigint: [%d] %s\n", status, message);
}

static volatile sig_atomic_t host_handler_ran;
static void host_handler(int sig)
{
    (void)sig;
    host_handler_ran = 1;
}

static const char *disposition(void)
{
    struct sigaction now;
    sigaction(SIGINT, NULL, &now);
    if (now.sa_handler == SIG_DFL) return "default";
    if (now.sa_handler == SIG_IGN) return "ignore";
    if (now.sa_handler == host_handler) return "host";
    return "other";
}

#define CHECK(call, what)                                                                          \
    if ((call) > 1) {                                                                              \
        fprintf(stderr, "sigint: %s failed\n", what);                                              \
        return 1;                                                                                  \
    }

int main(int argc, char **argv)
{
    if (argc != 6) {
        fprintf(stderr, "usage: sigint UNZIPDIR MODELIDENTIFIER GUID VR MODE\n");
        return 2;
    }
    const char *dir = argv[1], *model = argv[2], *guid = argv[3], *mode = argv[5];
    const fmi2ValueReference vr = (fmi2ValueReference)strtoul(argv[4], NULL, 10);
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = strcmp(mode, "handler") == 0 ? host_handler : SIG_DFL;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, NULL);
    printf("before %s\n", disposition());
    const Api api = load_api(dir, model, "");
    /* a folder without characters that need percent-encoding (the test's choice) */
    char uri[PATH_MAX + 32];
    snprintf(uri, sizeof uri, "file://%s/resources", dir);
    static const Callbacks callbacks = {logger, calloc, free, NULL, NULL};
    fmi2Component c = api.instantiate("sigint", 1, guid, uri, &callbacks, 0, 0);
    if (!c) {
        fprintf(stderr, "sigint: fmi2Instantiate failed\n");
        return 1;
    }
    double y = 0.0;
    CHECK(api.setup(c, 0, 0.0, 0.0, 0, 0.0), "fmi2SetupExperiment")
    CHECK(api.enter(c), "fmi2EnterInitializationMode")
    CHECK(api.exit_(c), "fmi2ExitInitializationMode")
    for (int k = 0; k < 10; ++k) {
        CHECK(api.step(c, k * 0.01, 0.01, 1), "fmi2DoStep")
        CHECK(api.get_real(c, &vr, 1, &y), "fmi2GetReal")
    }
    printf("after %s\n", disposition());
    fflush(stdout);
    raise(SIGINT);
    if (host_handler_ran) {
        printf("host handler ran\n");
        api.free_(c);
        return 0;
    }
    printf("survived\n");
    api.free_(c);
    return 3;
}
