/*
 * runtime.c -- the embedded Python and pythonfmu's library (drillstring_fmi2.h).
 *
 *  - the interpreter: if the host process has no Python, the layer loads libpython with
 *    RTLD_GLOBAL and starts it with an explicit configuration (home, module search path: the
 *    build's record in resources/drillstring_fmu_python.cfg, each entry overridable by an
 *    environment variable); if the host already runs Python, that interpreter is used, and only
 *    if it is of the kind the FMU was built for: the recorded major.minor version and ABI (the
 *    SOABI its extension modules are built for, "cpython-311-x86_64-linux-gnu": implementation,
 *    version, ABI flags, platform). A process holds one Python (a second libpython would bind
 *    the host's global symbols); this layer is compiled against the headers of the FMU's
 *    Python (its macros, PyConfig), and the numpy and numba the FMU was built with exist for
 *    that ABI only: a Python host of another version or ABI gets a NULL from fmi2Instantiate
 *    naming both, before any of the FMU's Python code runs in it. The modules the FMU computes
 *    with (numpy, numba) are checked against the versions recorded there by
 *    drillstring_fmu_boot.prepare;
 *  - a self-contained FMU (build_fmus.py --self-contained) records "self-contained 1": its Python
 *    is bundled in resources/ (the record's paths are relative to it, the DRILLSTRING_FMU_*
 *    overrides do not apply), the machine's glibc must be at least the recorded one, and the
 *    libraries outside glibc that the bundle needs are the system's where it has them, else the
 *    FMU's copies ("fallback" lines), loaded before libpython;
 *  - the host's signal dispositions stay as they were: no handlers installed at the start, and
 *    the SIGINT handler CPython installs when its _signal module is first imported undone once,
 *    right after the start (Ctrl-C stops a C host as before);
 *  - nothing per instance: sys.path is restored after each instantiation, and the reference that
 *    pythonfmu 0.7.0 drops on each instantiation (it releases a borrowed reference to the entry
 *    module's dictionary) is given back;
 *  - pythonfmu's abort at process exit: its interpreter guard is a namespace-scope shared_ptr that
 *    an ELF destructor resets after the C++ static destructors freed it ("free(): corrupted
 *    unsorted chunks"); the layer pins the library and registers its finalizePythonInterpreter
 *    with __cxa_atexit after loading it, so that it runs first and leaves an empty pointer.
 */
#include "drillstring_fmi2.h"

#include <dlfcn.h>
#include <errno.h>
#include <gnu/libc-version.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* ---- Python's C API, resolved at run time ---------------------------------------------------- */
#define PY_FUNCTIONS(X)                                                                            \
    X(Py_IsInitialized)                                                                            \
    X(PyPreConfig_InitIsolatedConfig)                                                              \
    X(Py_PreInitialize)                                                                            \
    X(Py_GetVersion)                                                                               \
    X(PyConfig_InitIsolatedConfig)                                                                 \
    X(PyConfig_SetBytesString)                                                                     \
    X(PyWideStringList_Append)                                                                     \
    X(Py_DecodeLocale)                                                                             \
    X(PyMem_RawFree)                                                                               \
    X(Py_InitializeFromConfig)                                                                     \
    X(PyConfig_Clear)                                                                              \
    X(PyStatus_Exception)                                                                          \
    X(PyEval_SaveThread)                                                                           \
    X(PyGILState_Ensure)                                                                           \
    X(PyGILState_Release)                                                                          \
    X(PyImport_ImportModule)                                                                       \
    X(PyObject_CallMethod)                                                                         \
    X(PyObject_GetAttrString)                                                                      \
    X(PySys_GetObject)                                                                             \
    X(PyList_GetSlice)                                                                             \
    X(PyList_SetSlice)                                                                             \
    X(PyList_Size)                                                                                 \
    X(PyList_GetItem)                                                                              \
    X(PyList_Insert)                                                                               \
    X(PyTuple_GetItem)                                                                             \
    X(PyLong_AsLong)                                                                               \
    X(PyUnicode_AsUTF8)                                                                            \
    X(PyUnicode_DecodeFSDefault)                                                                   \
    X(PyErr_Fetch)                                                                                 \
    X(PyErr_Clear)                                                                                 \
    X(PyObject_Str)                                                                                \
    X(PyModule_GetDict)                                                                            \
    X(Py_IncRef)                                                                                   \
    X(Py_DecRef)

typedef struct {
#define DECLARE(name) __typeof__(&name) name;
    PY_FUNCTIONS(DECLARE)
#undef DECLARE
} PythonApi;

/* ---- process-wide data ----------------------------------------------------------------------- */
/* One lock for every copy of this layer in the process (each FMU has its own copy, loaded with
   RTLD_LOCAL): a unique symbol (STB_GNU_UNIQUE), which the dynamic loader binds to its first
   definition process-wide. It serializes what touches the shared interpreter's set-up: starting
   Python, instantiation (sys.path saved and restored around it), fmi2FreeInstance, fmi2Reset. */
EXPORT pthread_mutex_t drillstring_fmi2_process_lock = PTHREAD_MUTEX_INITIALIZER;
__asm__(".type drillstring_fmi2_process_lock, @gnu_unique_object");
#define g_lock drillstring_fmi2_process_lock
static PythonApi py;
PythonFmu ds_pf;
static int g_python_ready, g_python_started_here;
static char g_python_failure[ERR_LEN]; /* the reason, remembered: the interpreter stays */

/* ---- the Python runtime ---------------------------------------------------------------------- */
typedef struct {
    char *version, *libpython, *home; /* on the heap, like the Runtime itself */
    char *abi; /* the SOABI of the extension modules, NULL: not recorded (an older build) */
    char **sites;
    int n_sites;
    /* a self-contained FMU (build_fmus.py --self-contained): the Python is bundled in resources/
       (relative paths), the environment's overrides do not apply, the machine's glibc must be at
       least `glibc`, and each `fallbacks` library is loaded from the bundle if the system has no
       library of its name */
    int bundled;
    char *glibc;
    char **fallbacks;
    int n_fallbacks;
} Runtime;

static void runtime_free(Runtime *rt)
{
    if (!rt) return;
    free(rt->version);
    free(rt->libpython);
    free(rt->home);
    free(rt->abi);
    for (int i = 0; i < rt->n_sites; ++i) free(rt->sites[i]);
    free(rt->sites);
    free(rt->glibc);
    for (int i = 0; i < rt->n_fallbacks; ++i) free(rt->fallbacks[i]);
    free(rt->fallbacks);
    free(rt);
}

/* *field = value[0..len) on the heap; 0, or -1: out of memory. */
static int set_text(char **field, const char *value, size_t len)
{
    char *copy = strndup(value, len);
    if (!copy) return -1;
    free(*field);
    *field = copy;
    return 0;
}

/* value[0..len) appended to the list (*items)[0..*n) on the heap; 0, or -1: out of memory. */
static int add_item(char ***items, int *n, const char *value, size_t len)
{
    char **grown = realloc(*items, (size_t)(*n + 1) * sizeof *grown);
    if (!grown) return -1;
    *items = grown;
    grown[*n] = NULL;
    if (set_text(&grown[*n], value, len) != 0) return -1;
    ++*n;
    return 0;
}

static int add_site(Runtime *rt, const char *value, size_t len)
{
    return add_item(&rt->sites, &rt->n_sites, value, len);
}

/* A path of the record relative to the resources folder made absolute; 0, or -1: out of memory. */
static int absolute(char **field, const char *resources)
{
    if (!*field || (*field)[0] == '/') return 0;
    char *path = ds_strf("%s/%s", resources, *field);
    if (!path) return -1;
    free(*field);
    *field = path;
    return 0;
}

static void clear_sites(Runtime *rt)
{
    for (int i = 0; i < rt->n_sites; ++i) free(rt->sites[i]);
    rt->n_sites = 0;
}

/* The build's record (resources/drillstring_fmu_python.cfg), then the environment's overrides;
   NULL with the reason in err. */
static Runtime *read_runtime(const char *resources, char *err, size_t errn)
{
    Runtime *rt = calloc(1, sizeof *rt);
    char *path = ds_strf("%s/%s", resources, RUNTIME_FILE), *line = NULL;
    if (!rt || !path) {
        ds_format(err, errn, "out of memory");
        goto fail;
    }
    FILE *fp = fopen(path, "r");
    if (!fp) {
        ds_format(err, errn, "cannot read %s: %s", path, strerror(errno));
        goto fail;
    }
    size_t cap = 0;
    int bad = 0;
    while (!bad && getline(&line, &cap, fp) >= 0) {
        line[strcspn(line, "\r\n")] = '\0';
        if (!line[0] || line[0] == '#') continue;
        char *value = strchr(line, ' ');
        if (!value) continue;
        *value++ = '\0';
        const size_t n = strlen(value);
        if (strcmp(line, "version") == 0) bad = set_text(&rt->version, value, n);
        else if (strcmp(line, "libpython") == 0) bad = set_text(&rt->libpython, value, n);
        else if (strcmp(line, "home") == 0) bad = set_text(&rt->home, value, n);
        else if (strcmp(line, "abi") == 0) bad = set_text(&rt->abi, value, n);
        else if (strcmp(line, "site") == 0) bad = add_site(rt, value, n);
        else if (strcmp(line, "self-contained") == 0) rt->bundled = strcmp(value, "1") == 0;
        else if (strcmp(line, "glibc") == 0) bad = set_text(&rt->glibc, value, n);
        else if (strcmp(line, "fallback") == 0)
            bad = add_item(&rt->fallbacks, &rt->n_fallbacks, value, n);
    }
    fclose(fp);
    const char *env;
    /* a self-contained FMU runs its own Python, whatever the environment says */
    if (!bad && !rt->bundled && (env = getenv("DRILLSTRING_FMU_LIBPYTHON")) && env[0])
        bad = set_text(&rt->libpython, env, strlen(env));
    if (!bad && !rt->bundled && (env = getenv("DRILLSTRING_FMU_PYTHONHOME")) && env[0])
        bad = set_text(&rt->home, env, strlen(env));
    if (!bad && !rt->bundled && (env = getenv("DRILLSTRING_FMU_SITE_PACKAGES")) && env[0]) {
        clear_sites(rt);
        for (const char *p = env; *p && !bad; ) {
            const size_t len = strcspn(p, ":");
            if (len > 0) bad = add_site(rt, p, len);
            p += len + (p[len] == ':');
        }
    }
    if (rt->bundled) { /* its paths are relative to the resources folder */
        bad = bad || absolute(&rt->libpython, resources) || absolute(&rt->home, resources);
        for (int i = 0; i < rt->n_sites && !bad; ++i) bad = absolute(&rt->sites[i], resources);
        for (int i = 0; i < rt->n_fallbacks && !bad; ++i)
            bad = absolute(&rt->fallbacks[i], resources);
    }
    if (bad) {
        ds_format(err, errn, "out of memory reading %s", path);
        goto fail;
    }
    if (!rt->version || !rt->libpython || !rt->home) {
        ds_format(err, errn, "%s lacks version, libpython or home", path);
        goto fail;
    }
    free(line);
    free(path);
    return rt;
fail:
    free(line);
    free(path);
    runtime_free(rt);
    return NULL;
}

static int resolve_python(void *where, char *err, size_t errn)
{
#define RESOLVE(name)                                                                              \
    if (!(py.name = (__typeof__(py.name))dlsym(where, #name))) {                                   \
        ds_format(err, errn, "the Python library lacks %s", #name);                                \
        return -1;                                                                                 \
    }
    PY_FUNCTIONS(RESOLVE)
#undef RESOLVE
    return 0;
}

static int append_path(PyConfig *config, const char *path)
{
    wchar_t *w = py.Py_DecodeLocale(path, NULL);
    if (!w) return -1;
    const PyStatus st = py.PyWideStringList_Append(&config->module_search_paths, w);
    py.PyMem_RawFree(w);
    return py.PyStatus_Exception(st) ? -1 : 0;
}

/* Py_GetVersion()'s "3.11.7 (main, ...)" is of the recorded major.minor "3.11". */
static int same_version(const char *version, const char *recorded)
{
    const size_t n = strlen(recorded);
    return strncmp(version, recorded, n) == 0 && (version[n] == '.' || version[n] == ' ');
}

/* Start the interpreter with an explicit configuration: nothing is guessed from PATH, PYTHONHOME
   or PYTHONPATH (isolated mode); the standard library of `home`, then the recorded site-packages
   (their .pth files are not processed, no user site: the FMU's own drillstring package wins).
   `lib` names the library that provides Python's functions, for the messages. */
static int start_python(const Runtime *rt, const char *lib, char *err, size_t errn)
{
    const char *version = py.Py_GetVersion();
    if (!same_version(version, rt->version)) {
        ds_format(err, errn, "%s is Python %.*s, but the FMU was built with Python %s "
                  "(set DRILLSTRING_FMU_LIBPYTHON and DRILLSTRING_FMU_PYTHONHOME to a Python %s)",
                  lib, (int)strcspn(version, " "), version, rt->version, rt->version);
        return -1;
    }
    int result = -1;
    char *nodots = strdup(rt->version);
    if (nodots) { /* "3.11" -> "311", for lib/python311.zip */
        char *q = nodots;
        for (const char *p = rt->version; *p; ++p)
            if (*p != '.') *q++ = *p;
        *q = '\0';
    }
    char *stdlib = ds_strf("%s/lib/python%s", rt->home, rt->version);
    char *probe = ds_strf("%s/lib/python%s/encodings/__init__.py", rt->home, rt->version);
    char *exe = ds_strf("%s/bin/python%s", rt->home, rt->version);
    char *zip = nodots ? ds_strf("%s/lib/python%s.zip", rt->home, nodots) : NULL;
    char *dynload = ds_strf("%s/lib/python%s/lib-dynload", rt->home, rt->version);
    if (!nodots || !stdlib || !probe || !exe || !zip || !dynload) {
        ds_format(err, errn, "out of memory");
        goto done;
    }
    if (access(probe, R_OK) != 0 && rt->bundled) {
        ds_format(err, errn, "the FMU's bundled Python '%s' has no standard library (%s is "
                  "missing: unpack the whole FMU)", rt->home, probe);
        goto done;
    }
    if (access(probe, R_OK) != 0) {
        ds_format(err, errn, "Python home '%s' has no standard library (%s is missing; set "
                  "DRILLSTRING_FMU_PYTHONHOME to the prefix of a Python %s installation)",
                  rt->home, probe, rt->version);
        goto done;
    }
    /* UTF-8 mode: file names are UTF-8 whatever the host's locale (a host that never called
       setlocale is in the C locale); the host's locale is not touched */
    PyPreConfig pre;
    py.PyPreConfig_InitIsolatedConfig(&pre);
    pre.utf8_mode = 1;
    const PyStatus pst = py.Py_PreInitialize(&pre);
    if (py.PyStatus_Exception(pst)) {
        ds_format(err, errn, "Python %s did not pre-initialize: %s", rt->version,
                  pst.err_msg ? pst.err_msg : "?");
        goto done;
    }
    PyConfig config;
    py.PyConfig_InitIsolatedConfig(&config);
    config.site_import = 0;
    config.install_signal_handlers = 0;
    config.module_search_paths_set = 1;
    int bad = py.PyStatus_Exception(py.PyConfig_SetBytesString(&config, &config.home, rt->home));
    if (!bad && access(exe, X_OK) == 0)
        bad = py.PyStatus_Exception(py.PyConfig_SetBytesString(&config, &config.executable, exe));
    bad = bad || append_path(&config, zip) || append_path(&config, stdlib) ||
          append_path(&config, dynload);
    for (int i = 0; i < rt->n_sites && !bad; ++i) bad = append_path(&config, rt->sites[i]);
    if (bad) {
        py.PyConfig_Clear(&config);
        ds_format(err, errn, "cannot configure the Python interpreter (out of memory?)");
        goto done;
    }
    /* The host's SIGINT disposition. install_signal_handlers = 0 keeps Python's handlers out at
       the start, but CPython 3.11 still installs its SIGINT handler when its _signal module is
       first imported (numba's imports do it), if the disposition is the default one: Ctrl-C then
       only sets a flag that no Python code polls, and the host runs on (and the next call into
       Python meets a KeyboardInterrupt). So _signal is imported here, once, and the host's
       disposition put back: a later import finds the module loaded and changes nothing. */
    struct sigaction host_sigint;
    const int saved_sigint = sigaction(SIGINT, NULL, &host_sigint) == 0;
    const PyStatus st = py.Py_InitializeFromConfig(&config);
    py.PyConfig_Clear(&config);
    if (py.PyStatus_Exception(st)) {
        ds_format(err, errn, "Python %s did not start: %s%s%s", rt->version,
                  st.func ? st.func : "", st.func ? ": " : "", st.err_msg ? st.err_msg : "?");
        goto done;
    }
    py.Py_DecRef(py.PyImport_ImportModule("_signal"));
    py.PyErr_Clear();
    if (saved_sigint) sigaction(SIGINT, &host_sigint, NULL);
    py.PyEval_SaveThread(); /* the GIL is taken per call (PyGILState_Ensure), from any thread */
    result = 0;
done:
    free(nodots);
    free(stdlib);
    free(probe);
    free(exe);
    free(zip);
    free(dynload);
    return result;
}

/* A text of the running interpreter (GIL held): sys.<name>, or sysconfig.get_config_var(name)
   if `config`; on the heap, or NULL (absent, not a string, out of memory). Only functions of
   Python's stable ABI are called: the interpreter may be of another version than the headers. */
static char *interpreter_text(const char *name, int config)
{
    PyObject *obj = NULL;
    if (config) {
        PyObject *sysconfig = py.PyImport_ImportModule("sysconfig");
        obj = sysconfig ? py.PyObject_CallMethod(sysconfig, "get_config_var", "s", name) : NULL;
        py.Py_DecRef(sysconfig);
    } else {
        obj = py.PySys_GetObject(name); /* borrowed */
        py.Py_IncRef(obj);
    }
    const char *text = obj ? py.PyUnicode_AsUTF8(obj) : NULL;
    char *out = text ? strdup(text) : NULL;
    py.PyErr_Clear();
    py.Py_DecRef(obj);
    return out;
}

/* The interpreter the slaves are to run in, started here (`borrowed` 0) or the host's, is of the
   recorded major.minor version and ABI (see the top of this file); 0, or -1 with the reason in
   err. Nothing of the FMU's runs in it before: only Py_GetVersion, sys and sysconfig are read. */
static int check_interpreter(const Runtime *rt, int borrowed, const char *lib,
                             const char *resources, char *err, size_t errn)
{
    const char *version = py.Py_GetVersion();
    const int vlen = (int)strcspn(version, " ");
    const PyGILState_STATE gil = py.PyGILState_Ensure();
    char *abi = interpreter_text("SOABI", 1), *exe = borrowed ? interpreter_text("executable", 0)
                                                              : NULL;
    py.PyGILState_Release(gil);
    const int ok = same_version(version, rt->version) &&
                   (!rt->abi || (abi && strcmp(abi, rt->abi) == 0));
    if (!ok && borrowed)
        ds_format(err, errn, "the host process runs Python %.*s (ABI %s; %s), but this FMU was "
                  "built with Python %s (ABI %s) and runs only in an interpreter of that version "
                  "and ABI (a process holds one Python; the FMU's front layer is compiled "
                  "against that Python's headers, and the numpy and numba it was built with "
                  "exist for that ABI only). Run the host on a Python %s with the packages of "
                  "%s/requirements.txt (pip install -r that file), or run the FMU from a host "
                  "that does not run Python: there it starts %s%s", vlen, version,
                  abi ? abi : "unknown", exe && exe[0] ? exe : "executable unknown", rt->version,
                  rt->abi ? rt->abi : "not recorded", rt->version, resources,
                  rt->bundled ? "the Python bundled in " : "the Python recorded in ",
                  rt->bundled ? resources
                              : RUNTIME_FILE " (DRILLSTRING_FMU_LIBPYTHON, DRILLSTRING_FMU_"
                                "PYTHONHOME and DRILLSTRING_FMU_SITE_PACKAGES override it)");
    else if (!ok)
        ds_format(err, errn, "%s is Python %.*s (ABI %s), but the FMU was built with Python %s "
                  "(ABI %s): set DRILLSTRING_FMU_LIBPYTHON and DRILLSTRING_FMU_PYTHONHOME to a "
                  "Python %s of that ABI", lib, vlen, version, abi ? abi : "unknown",
                  rt->version, rt->abi ? rt->abi : "not recorded", rt->version);
    free(abi);
    free(exe);
    return ok ? 0 : -1;
}

/* The site-packages folders, ':'-separated (on the heap), or NULL: out of memory. */
static char *joined_sites(const Runtime *rt)
{
    size_t n = 1;
    for (int i = 0; i < rt->n_sites; ++i) n += strlen(rt->sites[i]) + 1;
    char *out = malloc(n), *q = out;
    if (!out) return NULL;
    *q = '\0';
    for (int i = 0; i < rt->n_sites; ++i) q += sprintf(q, "%s%s", i ? ":" : "", rt->sites[i]);
    return out;
}

/* "2.36" as a number (2036), -1 if it is not of that form. */
static long glibc_number(const char *version)
{
    char *end = NULL;
    const long major = strtol(version, &end, 10);
    if (end == version || *end != '.') return -1;
    const char *minor_text = end + 1;
    const long minor = strtol(minor_text, &end, 10);
    if (end == minor_text) return -1;
    return major * 1000 + minor;
}

/* A self-contained FMU's bundle needs the machine's glibc to be at least the recorded version
   (the newest symbol version its binaries ask for); 0, or -1 with the reason in err. */
static int check_glibc(const Runtime *rt, char *err, size_t errn)
{
    if (!rt->glibc) return 0;
    const char *here = gnu_get_libc_version();
    const long need = glibc_number(rt->glibc), have = glibc_number(here);
    if (need < 0) {
        ds_format(err, errn, "the FMU's record asks for glibc '%s', which is not a version",
                  rt->glibc);
        return -1;
    }
    if (have >= 0 && have < need) {
        ds_format(err, errn, "this machine's glibc %s is older than glibc %s, the oldest the "
                  "self-contained FMU's bundled Python runs on (its binaries use symbols of glibc "
                  "%s)", here, rt->glibc, rt->glibc);
        return -1;
    }
    return 0;
}

/* A self-contained FMU's libraries that are not part of glibc (libffi, libz, libstdc++, ...):
   the system's if it has a library of that name, else the FMU's copy. Loaded before libpython and
   the extension modules that need them, which the dynamic loader then binds to the library
   already loaded under that name; 0, or -1 with the reason in err. */
static int load_fallbacks(Component *c, const Runtime *rt, char *err, size_t errn)
{
    for (int i = 0; i < rt->n_fallbacks; ++i) {
        const char *path = rt->fallbacks[i], *slash = strrchr(path, '/');
        const char *name = slash ? slash + 1 : path;
        if (dlopen(name, RTLD_NOW | RTLD_LOCAL)) continue;
        if (!dlopen(path, RTLD_NOW | RTLD_LOCAL)) {
            ds_format(err, errn, "cannot load %s: this machine has none, and the FMU's copy "
                      "'%s' does not load: %s", name, path, dlerror());
            return -1;
        }
        ds_logf(c, fmi2OK, "%s: not on this machine, the FMU's copy loaded (%s)", name, path);
    }
    return 0;
}

/* The interpreter the slaves run in: the host's if it has one, else ours (started once). */
static int ensure_python(Component *c, const char *resources)
{
    if (g_python_ready) {
        ds_logf(c, fmi2OK, "using the Python %.*s %s", (int)strcspn(py.Py_GetVersion(), " "),
                py.Py_GetVersion(), g_python_started_here ? "started by an FMU in this process"
                                                          : "that runs in the host process");
        return 0;
    }
    if (g_python_failure[0]) {
        ds_logf(c, fmi2Error, DS_FN_INSTANTIATE ": no Python for this FMU in this process (found "
                "at an earlier instantiation): %s", g_python_failure);
        return -1;
    }
    char *err = malloc(ERR_LEN);
    Runtime *rt = NULL;
    int result = -1;
    if (!err) {
        ds_logf(c, fmi2Error, DS_FN_INSTANTIATE ": out of memory");
        return -1; /* not remembered */
    }
    if (!(rt = read_runtime(resources, err, ERR_LEN))) goto fail;
    if (check_glibc(rt, err, ERR_LEN) != 0 || load_fallbacks(c, rt, err, ERR_LEN) != 0) goto fail;
    void *where = RTLD_DEFAULT;
    const int present = dlsym(RTLD_DEFAULT, "Py_IsInitialized") != NULL;
    if (!present) {
        where = dlopen(rt->libpython, RTLD_NOW | RTLD_GLOBAL);
        if (!where && rt->bundled) {
            ds_logf(c, fmi2Error, DS_FN_INSTANTIATE ": cannot load the FMU's bundled libpython "
                    "'%s': %s", rt->libpython, dlerror());
            goto done;
        }
        if (!where) {
            ds_logf(c, fmi2Error, DS_FN_INSTANTIATE ": cannot load libpython '%s': %s (set "
                    "DRILLSTRING_FMU_LIBPYTHON to the libpython%s.so of a Python %s with numpy)",
                    rt->libpython, dlerror(), rt->version, rt->version);
            goto done; /* not remembered: the environment may be fixed for the next attempt */
        }
    }
    if (resolve_python(where, err, ERR_LEN) != 0) goto fail;
    const char *lib = present ? "the Python library of the host process" : rt->libpython;
    const int borrowed = py.Py_IsInitialized();
    if (!borrowed && start_python(rt, lib, err, ERR_LEN) != 0) goto fail;
    if (check_interpreter(rt, borrowed, lib, resources, err, ERR_LEN) != 0) goto fail;
    if (!borrowed) {
        g_python_started_here = 1;
        for (int i = 0; i < rt->n_sites; ++i)
            if (!ds_is_dir(rt->sites[i]))
                ds_logf(c, fmi2Warning, DS_FN_INSTANTIATE ": site-packages folder '%s' does not exist "
                        "(%s)", rt->sites[i], rt->bundled ? "unpack the whole FMU"
                                                          : "set DRILLSTRING_FMU_SITE_PACKAGES");
        char *sites = joined_sites(rt);
        ds_logf(c, fmi2OK, "started Python %.*s from %s (home %s, site-packages %s)",
                (int)strcspn(py.Py_GetVersion(), " "), py.Py_GetVersion(), rt->libpython,
                rt->home, sites ? sites : "(out of memory)");
        free(sites);
    } else {
        ds_logf(c, fmi2OK, "using the Python %.*s that runs in the host process",
                (int)strcspn(py.Py_GetVersion(), " "), py.Py_GetVersion());
    }
    g_python_ready = 1;
    result = 0;
    goto done;
fail:
    ds_format(g_python_failure, sizeof g_python_failure, "%s", err);
    ds_logf(c, fmi2Error, DS_FN_INSTANTIATE ": %s", err);
done:
    runtime_free(rt);
    free(err);
    return result;
}

/* ---- pythonfmu's library --------------------------------------------------------------------- */
static void exit_guard(void *unused)
{
    (void)unused;
    if (ds_pf.finalizePythonInterpreter) ds_pf.finalizePythonInterpreter();
}

extern int __cxa_atexit(void (*)(void *), void *, void *);
static int load_library(Component *c, const char *path, const char *self);

static int load_pythonfmu(Component *c)
{
    if (ds_pf.lib) return 0;
    Dl_info info;
    if (!dladdr((void *)&load_pythonfmu, &info) || !info.dli_fname) {
        ds_logf(c, fmi2Error, DS_FN_INSTANTIATE ": cannot locate the FMU's own library");
        return -1;
    }
    const char *slash = strrchr(info.dli_fname, '/');
    const int dir = slash ? (int)(slash - info.dli_fname + 1) : 0;
    char *path = ds_strf("%.*s%s_pythonfmu.so", dir, info.dli_fname, DS_MODEL_IDENTIFIER);
    if (!path) {
        ds_logf(c, fmi2Error, DS_FN_INSTANTIATE ": out of memory");
        return -1;
    }
    const int ok = load_library(c, path, info.dli_fname);
    free(path);
    return ok;
}

/* pythonfmu's library at `path`, and the guard of its exit; 0 or -1 (logged). */
static int load_library(Component *c, const char *path, const char *self)
{
    /* pinned: Python keeps pointers into it, and the exit guard below must stay valid */
    dlopen(self, RTLD_NOW | RTLD_NOLOAD | RTLD_NODELETE);
    void *lib = dlopen(path, RTLD_NOW | RTLD_LOCAL | RTLD_NODELETE);
    if (!lib) {
        ds_logf(c, fmi2Error, DS_FN_INSTANTIATE ": cannot load pythonfmu's library %s: %s", path,
                dlerror());
        return -1;
    }
#define LOAD(field, name)                                                                          \
    if (!(ds_pf.field = (__typeof__(ds_pf.field))dlsym(lib, name))) {                              \
        ds_logf(c, fmi2Error, DS_FN_INSTANTIATE ": %s lacks %s", path, name);                         \
        return -1;                                                                                 \
    }
    LOAD(Instantiate, "fmi2Instantiate")
    LOAD(FreeInstance, "fmi2FreeInstance")
    LOAD(SetupExperiment, "fmi2SetupExperiment")
    LOAD(EnterInitializationMode, "fmi2EnterInitializationMode")
    LOAD(ExitInitializationMode, "fmi2ExitInitializationMode")
    LOAD(Terminate, "fmi2Terminate")
    LOAD(Reset, "fmi2Reset")
    LOAD(GetReal, "fmi2GetReal")
    LOAD(GetInteger, "fmi2GetInteger")
    LOAD(GetBoolean, "fmi2GetBoolean")
    LOAD(GetString, "fmi2GetString")
    LOAD(SetReal, "fmi2SetReal")
    LOAD(SetInteger, "fmi2SetInteger")
    LOAD(SetBoolean, "fmi2SetBoolean")
    LOAD(SetString, "fmi2SetString")
    LOAD(GetFMUstate, "fmi2GetFMUstate")
    LOAD(SetFMUstate, "fmi2SetFMUstate")
    LOAD(FreeFMUstate, "fmi2FreeFMUstate")
    LOAD(SerializedFMUstateSize, "fmi2SerializedFMUstateSize")
    LOAD(SerializeFMUstate, "fmi2SerializeFMUstate")
    LOAD(DeSerializeFMUstate, "fmi2DeSerializeFMUstate")
    LOAD(DoStep, "fmi2DoStep")
    LOAD(finalizePythonInterpreter, "finalizePythonInterpreter")
#undef LOAD
    /* after the library's static constructors: runs before its static destructors at exit */
    if (__cxa_atexit(exit_guard, NULL, NULL) != 0) {
        ds_logf(c, fmi2Error, DS_FN_INSTANTIATE ": cannot register the exit guard of %s", path);
        return -1;
    }
    ds_pf.lib = lib;
    return 0;
}

/* ---- Python helpers (GIL held) --------------------------------------------------------------- */
static void log_python_error(Component *c, const char *fn, const char *what)
{
    PyObject *type = NULL, *value = NULL, *tb = NULL;
    py.PyErr_Fetch(&type, &value, &tb);
    PyObject *text = value ? py.PyObject_Str(value) : NULL;
    const char *s = text ? py.PyUnicode_AsUTF8(text) : NULL;
    ds_logf(c, fmi2Error, "%s: %s: %s", fn, what, s ? s : "unknown Python error");
    if (!s) py.PyErr_Clear();
    py.Py_DecRef(text);
    py.Py_DecRef(type);
    py.Py_DecRef(value);
    py.Py_DecRef(tb);
}

/* drillstring_fmu_boot.prepare(resources, entry module, borrowed): forwards its records, returns
   the resources path for pythonfmu (on the heap), or NULL. */
static char *boot(Component *c, const char *resources)
{
    PyObject *sys_path = py.PySys_GetObject("path"); /* borrowed */
    PyObject *dir = py.PyUnicode_DecodeFSDefault(resources);
    if (!sys_path || !dir || py.PyList_Insert(sys_path, 0, dir) != 0) {
        py.Py_DecRef(dir);
        log_python_error(c, DS_FN_INSTANTIATE, "cannot put the resources folder on sys.path");
        return NULL;
    }
    py.Py_DecRef(dir);
    PyObject *module = py.PyImport_ImportModule(BOOT_MODULE);
    if (!module) {
        log_python_error(c, DS_FN_INSTANTIATE, "cannot import " BOOT_MODULE);
        return NULL;
    }
    PyObject *result = py.PyObject_CallMethod(module, "prepare", "ssi", resources, DS_ENTRY_MODULE,
                                              !g_python_started_here);
    py.Py_DecRef(module);
    if (!result) {
        log_python_error(c, DS_FN_INSTANTIATE, BOOT_MODULE ".prepare failed");
        return NULL;
    }
    PyObject *path = py.PyTuple_GetItem(result, 0), *records = py.PyTuple_GetItem(result, 1);
    const Py_ssize_t n = records ? py.PyList_Size(records) : 0;
    for (Py_ssize_t i = 0; i < n; ++i) {
        PyObject *r = py.PyList_GetItem(records, i);
        const long status = py.PyLong_AsLong(py.PyTuple_GetItem(r, 0));
        const char *category = py.PyUnicode_AsUTF8(py.PyTuple_GetItem(r, 1));
        const char *message = py.PyUnicode_AsUTF8(py.PyTuple_GetItem(r, 2));
        if (!message) {
            py.PyErr_Clear();
            message = "(a message of " BOOT_MODULE " that is not valid UTF-8)";
        }
        if (status > c->call_status) c->call_status = (fmi2Status)status;
        ds_emit(c, (fmi2Status)status, category ? category : ds_status_category(status), message);
    }
    const char *p = path ? py.PyUnicode_AsUTF8(path) : NULL; /* None: failed */
    char *out = p ? strdup(p) : NULL;
    if (p && !out) ds_logf(c, fmi2Error, DS_FN_INSTANTIATE ": out of memory");
    py.PyErr_Clear();
    py.Py_DecRef(result);
    return out;
}

/* The entry module's dictionary (borrowed) and its reference count. */
static PyObject *entry_dict(void)
{
    PyObject *module = py.PyImport_ImportModule(DS_ENTRY_MODULE);
    if (!module) {
        py.PyErr_Clear();
        return NULL;
    }
    PyObject *d = py.PyModule_GetDict(module);
    py.Py_DecRef(module);
    return d;
}


/* ---- the Python side of each instance (GIL held) --------------------------------------------- */
/* drillstring_fmu_boot.<function>(component[, the layer's typed calls]): the slave being made
   takes the addresses of ds_front_fast and ds_front_log (the typed calls through which it hands
   over its fast path and its messages, never through pythonfmu's log queue) and registers for
   its release; 0, or -1 (logged, prefixed with `fn`). */
static int boot_call(Component *c, const char *fn, const char *function)
{
    const unsigned long long self = (uintptr_t)c;
    PyObject *module = py.PyImport_ImportModule(BOOT_MODULE), *result = NULL;
    if (module && strcmp(function, "begin_instance") == 0)
        result = py.PyObject_CallMethod(module, function, "KKK", self,
                                        (unsigned long long)(uintptr_t)&ds_front_fast,
                                        (unsigned long long)(uintptr_t)&ds_front_log);
    else if (module)
        result = py.PyObject_CallMethod(module, function, "K", self);
    py.Py_DecRef(module);
    if (!result) {
        log_python_error(c, fn, BOOT_MODULE " failed");
        return -1;
    }
    py.Py_DecRef(result);
    return 0;
}

/* pythonfmu 0.7.0 puts its resources path at sys.path[0] with a reference it never releases (a
   new string given to PyList_Insert, which does not steal it): once sys.path is restored, that
   string would live on, ~200 bytes per instance. Its leaked reference is released if sys.path[0]
   is that string and held by nothing else (two references: sys.path's and the leaked one). */
static void release_leaked_path(PyObject *sys_path, const char *path)
{
    PyObject *first = py.PyList_Size(sys_path) > 0 ? py.PyList_GetItem(sys_path, 0) : NULL;
    if (!first || !PyUnicode_Check(first) || Py_REFCNT(first) != 2) return;
    const char *text = py.PyUnicode_AsUTF8(first);
    if (text && strcmp(text, path) == 0) py.Py_DecRef(first);
}

/* ---- instances ------------------------------------------------------------------------------- */
int ds_python_instantiate(Component *c, const char *resources, fmi2String guid,
                          fmi2Boolean visible)
{
    char *for_pythonfmu = NULL, *uri = NULL;
    pthread_mutex_lock(&g_lock);
    if (ensure_python(c, resources) != 0 || load_pythonfmu(c) != 0) {
        pthread_mutex_unlock(&g_lock);
        return -1;
    }
    PyGILState_STATE gil = py.PyGILState_Ensure();
    PyObject *sys_path = py.PySys_GetObject("path");
    PyObject *saved = sys_path ? py.PyList_GetSlice(sys_path, 0, PY_SSIZE_T_MAX) : NULL;
    if (saved) for_pythonfmu = boot(c, resources);
    const int booted = for_pythonfmu && boot_call(c, DS_FN_INSTANTIATE, "begin_instance") == 0;
    /* pythonfmu 0.7.0 releases a borrowed reference to the entry module's dictionary at each
       instantiation (findClass: Py_DECREF of PyModule_GetDict's result); that dictionary has one
       reference (its module), so it would be freed under the module: lend it one beforehand */
    PyObject *dict = booted ? entry_dict() : NULL;
    const Py_ssize_t refs = dict ? Py_REFCNT(dict) : 0;
    if (dict) py.Py_IncRef(dict);
    py.PyGILState_Release(gil);

    if (booted && !(uri = ds_strf("file://%s", for_pythonfmu)))
        ds_logf(c, fmi2Error, DS_FN_INSTANTIATE ": out of memory");
    const int called = uri != NULL;
    if (called)
        c->inner = ds_pf.Instantiate(c->name, fmi2CoSimulation, guid, uri, &c->callbacks, visible,
                                     fmi2True);
    free(uri);

    gil = py.PyGILState_Ensure();
    if (booted) boot_call(c, DS_FN_INSTANTIATE, "end_instance");
    if (dict && Py_REFCNT(dict) > refs) py.Py_DecRef(dict); /* not taken: a pythonfmu without
                                                                   that defect, or it failed */
    if (saved) { /* sys.path as it was: pythonfmu and the boot module added to it */
        sys_path = py.PySys_GetObject("path");
        if (sys_path && called) release_leaked_path(sys_path, for_pythonfmu);
        if (sys_path) py.PyList_SetSlice(sys_path, 0, PY_SSIZE_T_MAX, saved);
        py.Py_DecRef(saved);
    }
    py.PyErr_Clear();
    py.PyGILState_Release(gil);
    pthread_mutex_unlock(&g_lock);
    free(for_pythonfmu);

    if (!c->inner) {
        if (called)
            ds_logf(c, fmi2Error, DS_FN_INSTANTIATE ": pythonfmu could not create the slave (see the "
                    "message before)");
        return -1;
    }
    return 0;
}

void ds_python_free(Component *c)
{
    if (!c->inner) return;
    pthread_mutex_lock(&g_lock);
    ds_fast_drop(c);
    ds_states_free_owned(c);
    /* the slave drops its model and the cycles through itself: pythonfmu's fmi2FreeInstance
       then frees it at once, not at some later run of Python's cyclic garbage collector */
    PyGILState_STATE gil = py.PyGILState_Ensure();
    boot_call(c, DS_FN("fmi2FreeInstance", "fmi3FreeInstance"), "release");
    py.PyErr_Clear();
    py.PyGILState_Release(gil);
    ds_pf.FreeInstance(c->inner);
    c->inner = NULL;
    pthread_mutex_unlock(&g_lock);
}

fmi2Status ds_python_reset(Component *c)
{
    pthread_mutex_lock(&g_lock);
    ds_fast_drop(c);
    /* pythonfmu's fmi2Reset replaces the slave: the old one released, the new one handed over */
    PyGILState_STATE gil = py.PyGILState_Ensure();
    boot_call(c, DS_FN("fmi2Reset", "fmi3Reset"), "release");
    const int handed = boot_call(c, DS_FN("fmi2Reset", "fmi3Reset"), "begin_instance") == 0;
    py.PyErr_Clear();
    py.PyGILState_Release(gil);
    const fmi2Status s = ds_finish(c, ds_pf.Reset(c->inner));
    gil = py.PyGILState_Ensure();
    if (handed) boot_call(c, DS_FN("fmi2Reset", "fmi3Reset"), "end_instance");
    py.PyErr_Clear();
    py.PyGILState_Release(gil);
    pthread_mutex_unlock(&g_lock);
    return s;
}
