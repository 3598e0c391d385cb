/*
 * log.c -- what reaches the host's logger (drillstring_fmi2.h).
 *
 * Warnings, discards and errors always reach the host, info only when logging is on for its
 * category. The Python slave reports problems as log messages (it never raises into pythonfmu):
 * each message's status counts into the status of the call in which it is logged
 * (Component.call_status, see ds_finish in machine.c). The message of a discarded step comes with
 * the time the FMU reached, as a double (for the last successful time, see ds_do_step in machine.c).
 */
#include "drillstring_fmi2.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int ds_category_index(const char *category)
{
    for (int i = 0; category && DS_LOG_CATEGORIES[i]; ++i)
        if (strcmp(DS_LOG_CATEGORIES[i], category) == 0) return i;
    return -1;
}

const char *ds_status_category(fmi2Status status)
{
    switch (status) {
    case fmi2Warning: return "logStatusWarning";
    case fmi2Discard: return "logStatusDiscard";
    case fmi2Error: return "logStatusError";
    case fmi2Fatal: return "logStatusFatal";
    default: return "logInfo";
    }
}

/* Forward one message to the host: always for warnings and worse, info only when logging is on
   for its category. FMI 2.0: '%' is doubled, hosts format the message as a printf format; FMI 3.0
   passes the message as it is. */
void ds_emit(Component *c, fmi2Status status, const char *category, const char *message)
{
    if (!c->host.logger && !c->log3) return;
    if (!category || ds_category_index(category) < 0) category = ds_status_category(status);
    if (status == fmi2OK || status == fmi2Pending) {
        const int i = ds_category_index(category), all = ds_category_index("logAll");
        if (!c->logging_on || !(c->category_on[i] || (all >= 0 && c->category_on[all]))) return;
    }
#ifdef DS_FMI3
    if (c->log3) {
        /* the Python slave names the FMI 2.0 call pythonfmu made ("fmi2DoStep: ..."): the host
           reads the name of its FMI 3.0 call instead; FMI 3.0 has no status fmi2Pending */
        const int fmi2 = strncmp(message, "fmi2", 4) == 0;
        const size_t k = fmi2 ? 4 + strspn(message + 4, "ABCDEFGHIJKLMNOPQRSTUVWXYZ"
                                                         "abcdefghijklmnopqrstuvwxyz") : 0;
        char *renamed = fmi2 && message[k] == ':' && c->call
                            ? ds_strf("%s%s", c->call, message + k) : NULL;
        c->log3(c->host.componentEnvironment, status == fmi2Pending ? fmi2OK : status, category,
                renamed ? renamed : message);
        free(renamed);
        return;
    }
#endif
    size_t n = 1;
    for (const char *p = message; *p; ++p) n += (*p == '%') ? 2 : 1;
    char *text = malloc(n);
    if (!text) return;
    char *q = text;
    for (const char *p = message; *p; ++p) {
        *q++ = *p;
        if (*p == '%') *q++ = '%';
    }
    *q = '\0';
    c->host.logger(c->host.componentEnvironment, c->name, status, category, text);
    free(text);
}

/* ---- formatting ------------------------------------------------------------------------------ */
static const char CUT[] = "...";

/* A text cut to out[cap] ends in "...": a shortened message is visibly shortened. */
static void mark_cut(char *out, size_t cap)
{
    if (cap >= sizeof CUT) memcpy(out + cap - sizeof CUT, CUT, sizeof CUT);
}

int ds_format(char *out, size_t cap, const char *fmt, ...)
{
    va_list args;
    va_start(args, fmt);
    const int n = vsnprintf(out, cap, fmt, args);
    va_end(args);
    if (n >= 0 && (size_t)n < cap) return 0;
    if (n < 0 && cap > 0) out[0] = '\0';
    mark_cut(out, cap);
    return -1;
}

char *ds_strf(const char *fmt, ...)
{
    char *out = NULL;
    va_list args;
    va_start(args, fmt);
    const int n = vasprintf(&out, fmt, args);
    va_end(args);
    return n < 0 ? NULL : out;
}

/* Format (on the heap if longer than 1 KiB), count into the call's status and forward. */
static void vlog(Component *c, fmi2Status status, const char *fmt, va_list args)
{
    char small[1024], *text = small, *big = NULL;
    va_list again;
    va_copy(again, args);
    const int n = vsnprintf(small, sizeof small, fmt, args);
    if (n < 0) {
        ds_format(small, sizeof small, "(a message that cannot be formatted: %s)", fmt);
    } else if ((size_t)n >= sizeof small) { /* longer: on the heap, or cut if there is none */
        big = malloc((size_t)n + 1);
        if (big && vsnprintf(big, (size_t)n + 1, fmt, again) == n) text = big;
        else mark_cut(small, sizeof small);
    }
    va_end(again);
    if (status > c->call_status && status != fmi2Pending) c->call_status = status;
    ds_emit(c, status, NULL, text);
    free(big);
}

void ds_logf(Component *c, fmi2Status status, const char *fmt, ...)
{
    va_list args;
    va_start(args, fmt);
    vlog(c, status, fmt, args);
    va_end(args);
}

int32_t ds_front_log(void *component, int32_t status, const char *category, const char *message,
                     const double *reached)
{
    Component *c = component;
    if (!c || c->magic != COMPONENT_MAGIC) return -1;
    if (!message || status < (int32_t)fmi2OK || status > (int32_t)fmi2Pending) return 1;
    const fmi2Status st = (fmi2Status)status;
    if (reached) {
        c->reached = *reached;
        c->has_reached = 1;
    }
    if (st > c->call_status && st != fmi2Pending) c->call_status = st;
    ds_emit(c, st, category, message);
    return 0;
}

/* The logger pythonfmu calls (messages passed without format arguments: the slave's, when it
   has no typed call, and pythonfmu's own). */
void ds_slave_logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                     fmi2String category, fmi2String message, ...)
{
    (void)instance;
    ds_front_log(env, (int32_t)status, category, message, NULL);
}
