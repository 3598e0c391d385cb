/*
 * states.c -- FMU states in an envelope (drillstring_fmi2.h).
 *
 * An FMU state is pythonfmu's state plus what the layer owns (the state-machine state and
 * fmi2LastSuccessfulTime); the layer keeps a list of the states it handed out, so that a pointer
 * that is not one of them (a state of another FMU, or one freed already) is refused before Python
 * sees it. A serialized state is a header (model, GUID, format, state-machine state, time, length,
 * FNV-1a checksum) and pythonfmu's bytes: a state of another FMU or corrupted bytes are refused
 * with a message that says which. The checksum is no authentication (anyone can recompute it):
 * the slave checks a state's content against the instance before it overwrites anything
 * (drillstring_fmu_support.FmuModel._set_fmu_state). A state belongs to the instance that made it (another instance
 * of the same FMU may set it): fmi2FreeInstance frees the states the instance still owns.
 */
#include "drillstring_fmi2.h"

#include <stdlib.h>
#include <string.h>
#include <stdio.h>

#define STATE_MAGIC 0x44534649325354ULL
/* the names of the calls, in the messages */
#define FN_GET DS_FN("fmi2GetFMUstate", "fmi3GetFMUState")
#define FN_SET DS_FN("fmi2SetFMUstate", "fmi3SetFMUState")
#define FN_FREE DS_FN("fmi2FreeFMUstate", "fmi3FreeFMUState")
#define FN_SIZE DS_FN("fmi2SerializedFMUstateSize", "fmi3SerializedFMUStateSize")
#define FN_SERIALIZE DS_FN("fmi2SerializeFMUstate", "fmi3SerializeFMUState")
#define FN_DESERIALIZE DS_FN("fmi2DeSerializeFMUstate", "fmi3DeserializeFMUState")

/* An FMU state: pythonfmu's state plus what the layer owns. */
typedef struct State {
    uint64_t magic;
    const Component *owner; /* the instance that made it: fmi2FreeInstance frees it */
    int phase;
    double last_time;
    fmi2FMUstate inner;
    struct State *next;
} State;

/* Serialized FMU state: this header, then pythonfmu's bytes. */
typedef struct {
    char magic[8];
    uint32_t format;
    uint32_t phase;
    double last_time;
    char model[64];
    char guid[64];
    uint64_t payload_size;
    uint64_t checksum; /* FNV-1a 64 of the header (checksum 0) and the payload */
} StateHeader;
#define STATE_FORMAT 1
_Static_assert(sizeof DS_MODEL_IDENTIFIER <= sizeof ((StateHeader *)0)->model,
               "the model identifier does not fit into the FMU state's header");
_Static_assert(sizeof DS_GUID <= sizeof ((StateHeader *)0)->guid,
               "the GUID does not fit into the FMU state's header");
static const char STATE_HEADER_MAGIC[8] = "DSFMI2S";

static pthread_mutex_t g_state_lock = PTHREAD_MUTEX_INITIALIZER; /* the list of FMU states */
static State *g_states;

static int state_known(const State *s)
{
    int found = 0;
    pthread_mutex_lock(&g_state_lock);
    for (const State *p = g_states; p && !found; p = p->next) found = (p == s);
    pthread_mutex_unlock(&g_state_lock);
    return found && s->magic == STATE_MAGIC;
}

static void state_add(State *s)
{
    pthread_mutex_lock(&g_state_lock);
    s->next = g_states;
    g_states = s;
    pthread_mutex_unlock(&g_state_lock);
}

static void state_remove(State *s)
{
    pthread_mutex_lock(&g_state_lock);
    for (State **p = &g_states; *p; p = &(*p)->next) {
        if (*p == s) {
            *p = s->next;
            break;
        }
    }
    pthread_mutex_unlock(&g_state_lock);
    s->magic = 0;
    free(s);
}

void ds_states_free_owned(Component *c)
{
    for (;;) {
        State *s = NULL;
        pthread_mutex_lock(&g_state_lock);
        for (State **p = &g_states; *p; p = &(*p)->next) {
            if ((*p)->owner == c) {
                s = *p;
                *p = s->next;
                break;
            }
        }
        pthread_mutex_unlock(&g_state_lock);
        if (!s) return;
        ds_pf.FreeFMUstate(c->inner, &s->inner);
        s->magic = 0;
        free(s);
    }
}

static int check_state(Component *c, const char *fn, const void *s)
{
    if (!s) {
        ds_logf(c, fmi2Error, "%s: the FMU state is NULL", fn);
        return 0;
    }
    if (!state_known(s)) {
        ds_logf(c, fmi2Error, "%s: %p is not an FMU state of %s (one of another FMU, or freed "
                "already); nothing done", fn, s, DS_MODEL_IDENTIFIER);
        return 0;
    }
    return 1;
}

fmi2Status ds_state_get(Component *c, fmi2FMUstate *FMUstate)
{
    if (!FMUstate) {
        ds_logf(c, fmi2Error, FN_GET ": FMUstate is NULL");
        return fmi2Error;
    }
    State *s = *FMUstate;
    if (s && !check_state(c, FN_GET " (to overwrite)", s)) return fmi2Error;
    fmi2FMUstate inner = NULL;
    ds_fast_drop(c);
    const fmi2Status st = ds_finish(c, ds_pf.GetFMUstate(c->inner, &inner));
    if (st > fmi2Warning) {
        if (inner) ds_pf.FreeFMUstate(c->inner, &inner);
        return st;
    }
    if (s) {
        ds_pf.FreeFMUstate(c->inner, &s->inner);
    } else {
        s = calloc(1, sizeof *s);
        if (!s) {
            ds_pf.FreeFMUstate(c->inner, &inner);
            ds_logf(c, fmi2Error, FN_GET ": out of memory");
            return fmi2Error;
        }
        s->magic = STATE_MAGIC;
        s->owner = c;
        state_add(s);
    }
    s->inner = inner;
    s->phase = c->state;
    s->last_time = c->last_time;
    *FMUstate = s;
    return st;
}

fmi2Status ds_state_set(Component *c, fmi2FMUstate FMUstate)
{
    if (!check_state(c, FN_SET, FMUstate)) return fmi2Error;
    State *s = FMUstate;
    ds_fast_drop(c);
    const fmi2Status st = ds_finish(c, ds_pf.SetFMUstate(c->inner, s->inner));
    if (st <= fmi2Warning) {
        c->state = s->phase;
        c->last_time = s->last_time;
    }
    return st;
}

fmi2Status ds_state_free(Component *c, fmi2FMUstate *FMUstate)
{
    if (!FMUstate || !*FMUstate) return fmi2OK;
    if (!check_state(c, FN_FREE, *FMUstate)) return fmi2Error;
    State *s = *FMUstate;
    const fmi2Status st = ds_finish(c, ds_pf.FreeFMUstate(c->inner, &s->inner));
    state_remove(s);
    *FMUstate = NULL;
    return st;
}

static uint64_t fnv1a(uint64_t h, const void *data, size_t n)
{
    const unsigned char *p = data;
    for (size_t i = 0; i < n; ++i) h = (h ^ p[i]) * 0x100000001b3ULL;
    return h;
}

static uint64_t checksum(const StateHeader *h, const void *payload)
{
    StateHeader copy = *h;
    copy.checksum = 0;
    return fnv1a(fnv1a(0xcbf29ce484222325ULL, &copy, sizeof copy), payload, h->payload_size);
}

fmi2Status ds_state_size(Component *c, fmi2FMUstate FMUstate, size_t *size)
{
    if (!check_state(c, FN_SIZE, FMUstate)) return fmi2Error;
    if (!size) {
        ds_logf(c, fmi2Error, FN_SIZE ": size is NULL");
        return fmi2Error;
    }
    size_t n = 0;
    ds_fast_drop(c);
    const fmi2Status st = ds_finish(c, ds_pf.SerializedFMUstateSize(
                                           c->inner, ((State *)FMUstate)->inner, &n));
    if (st <= fmi2Warning) *size = sizeof(StateHeader) + n;
    return st;
}

fmi2Status ds_state_serialize(Component *c, fmi2FMUstate FMUstate, fmi2Byte serializedState[],
                              size_t size)
{
    if (!check_state(c, FN_SERIALIZE, FMUstate)) return fmi2Error;
    State *s = FMUstate;
    size_t n = 0;
    ds_fast_drop(c);
    fmi2Status st = ds_finish(c, ds_pf.SerializedFMUstateSize(c->inner, s->inner, &n));
    if (st > fmi2Warning) return st;
    if (!serializedState || size != sizeof(StateHeader) + n) {
        ds_logf(c, fmi2Error, FN_SERIALIZE ": buffer of %zu bytes%s, the state needs %zu "
                "(" FN_SIZE ")", size, serializedState ? "" : " (NULL)",
                sizeof(StateHeader) + n);
        return fmi2Error;
    }
    ds_fast_drop(c);
    st = ds_finish(c, ds_pf.SerializeFMUstate(c->inner, s->inner,
                                              serializedState + sizeof(StateHeader), n));
    if (st > fmi2Warning) return st;
    StateHeader h;
    memset(&h, 0, sizeof h);
    memcpy(h.magic, STATE_HEADER_MAGIC, sizeof h.magic);
    h.format = STATE_FORMAT;
    h.phase = (uint32_t)s->phase;
    h.last_time = s->last_time;
    memcpy(h.model, DS_MODEL_IDENTIFIER, sizeof DS_MODEL_IDENTIFIER); /* both fit: see below */
    memcpy(h.guid, DS_GUID, sizeof DS_GUID);
    h.payload_size = n;
    h.checksum = checksum(&h, serializedState + sizeof(StateHeader));
    memcpy(serializedState, &h, sizeof h);
    return st;
}

fmi2Status ds_state_deserialize(Component *c, const fmi2Byte serializedState[], size_t size,
                                fmi2FMUstate *FMUstate)
{
    const char *fn = FN_DESERIALIZE;
    if (!FMUstate || !serializedState) {
        ds_logf(c, fmi2Error, "%s: %s is NULL", fn, FMUstate ? "serializedState" : "FMUstate");
        return fmi2Error;
    }
    State *s = *FMUstate;
    if (s && !check_state(c, FN_DESERIALIZE " (to overwrite)", s)) return fmi2Error;
    StateHeader h;
    if (size < sizeof h || memcmp(serializedState, STATE_HEADER_MAGIC, sizeof h.magic) != 0) {
        ds_logf(c, fmi2Error, "%s: %zu bytes that are not a serialized FMU state of a drillstring "
                "FMU; nothing done", fn, size);
        return fmi2Error;
    }
    memcpy(&h, serializedState, sizeof h);
    h.model[sizeof h.model - 1] = h.guid[sizeof h.guid - 1] = '\0';
    if (h.format != STATE_FORMAT) {
        ds_logf(c, fmi2Error, "%s: FMU state format %u, this FMU reads format %d; nothing done", fn,
                h.format, STATE_FORMAT);
        return fmi2Error;
    }
    if (strcmp(h.guid, DS_GUID) != 0) {
        ds_logf(c, fmi2Error, "%s: the bytes are an FMU state of %s (GUID %s), not of this FMU %s "
                "(GUID %s); nothing done", fn, h.model, h.guid, DS_MODEL_IDENTIFIER, DS_GUID);
        return fmi2Error;
    }
    if (h.payload_size != size - sizeof h) {
        ds_logf(c, fmi2Error, "%s: corrupted FMU state: %zu bytes, the header announces %llu; "
                "nothing done", fn, size, (unsigned long long)(h.payload_size + sizeof h));
        return fmi2Error;
    }
    if (checksum(&h, serializedState + sizeof h) != h.checksum ||
        !(h.phase & ST_ANY_LIVE) || (h.phase & (h.phase - 1))) {
        ds_logf(c, fmi2Error, "%s: corrupted FMU state: checksum mismatch; nothing done", fn);
        return fmi2Error;
    }
    fmi2FMUstate inner = NULL;
    ds_fast_drop(c);
    const fmi2Status st = ds_finish(c, ds_pf.DeSerializeFMUstate(
                                           c->inner, serializedState + sizeof h, h.payload_size,
                                           &inner));
    if (st > fmi2Warning) {
        if (inner) ds_pf.FreeFMUstate(c->inner, &inner);
        return st;
    }
    if (s) {
        ds_pf.FreeFMUstate(c->inner, &s->inner);
    } else {
        s = calloc(1, sizeof *s);
        if (!s) {
            ds_pf.FreeFMUstate(c->inner, &inner);
            ds_logf(c, fmi2Error, "%s: out of memory", fn);
            return fmi2Error;
        }
        s->magic = STATE_MAGIC;
        s->owner = c;
        state_add(s);
    }
    s->inner = inner;
    s->phase = (int)h.phase;
    s->last_time = h.last_time;
    *FMUstate = s;
    return st;
}
