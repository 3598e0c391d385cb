/*
 * uri.c -- the resource URI and the resources folder (drillstring_fmi2.h).
 *
 * The fmuResourceLocation is decoded fully (RFC 3986 / RFC 8089: file:/, file:///,
 * file://localhost/, percent-encoding; a plain absolute path is taken as it is) and the folder it
 * names is checked for the files of this FMU before pythonfmu sees it.
 */
#include "drillstring_fmi2.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

static int hexval(char ch)
{
    if (ch >= '0' && ch <= '9') return ch - '0';
    if (ch >= 'a' && ch <= 'f') return ch - 'a' + 10;
    if (ch >= 'A' && ch <= 'F') return ch - 'A' + 10;
    return -1;
}

int ds_is_dir(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0 && S_ISDIR(st.st_mode);
}

/* Percent-decode src[0..n) into out (room for n + 1 bytes: decoding never lengthens); 0, or -1
   with the reason in err. */
static int percent_decode(const char *src, size_t n, char *out, char *err, size_t errn)
{
    size_t k = 0;
    for (size_t i = 0; i < n; ++i) {
        char ch = src[i];
        if (ch == '%') {
            if (i + 2 >= n) {
                ds_format(err, errn, "incomplete percent-encoding at offset %zu", i);
                return -1;
            }
            const int hi = hexval(src[i + 1]), lo = hexval(src[i + 2]);
            if (hi < 0 || lo < 0) {
                ds_format(err, errn, "invalid percent-encoding '%.3s' at offset %zu", src + i, i);
                return -1;
            }
            ch = (char)(hi * 16 + lo);
            if (ch == '\0') {
                ds_format(err, errn, "percent-encoded NUL (%%00) at offset %zu", i);
                return -1;
            }
            i += 2;
        }
        out[k++] = ch;
    }
    out[k] = '\0';
    return 0;
}

/* The local folder a resource URI names (RFC 3986 / RFC 8089), without trailing '/'. */
static int decode(const char *uri, char *out, char *err, size_t errn)
{
    if (uri[0] == '/') { /* a plain absolute path: not a URI, taken as it is */
        strcpy(out, uri);
        return 0;
    }
    if (strncasecmp(uri, "file:", 5) != 0) {
        ds_format(err, errn, "fmuResourceLocation '%s' is not a file URI", uri);
        return -1;
    }
    const char *p = uri + 5;
    if (p[0] == '/' && p[1] == '/') { /* authority */
        const char *host = p + 2, *slash = strchr(host, '/');
        const size_t len = slash ? (size_t)(slash - host) : strlen(host);
        if (len > 0 && !(len == 9 && strncasecmp(host, "localhost", 9) == 0)) {
            ds_format(err, errn, "fmuResourceLocation '%s' names the host '%.*s', not a local "
                      "folder", uri, (int)len, host);
            return -1;
        }
        p = host + len;
    }
    if (p[0] != '/') {
        ds_format(err, errn, "fmuResourceLocation '%s' has no absolute path", uri);
        return -1;
    }
    /* '?' and '#' end the path (RFC 3986, 3.3). Hosts that do not encode their paths (the fmi4c
       library of Ecos passes "file://" + the plain path) are served too: if that path names no
       folder, the whole text, percent-decoded or else taken literally. */
    const size_t whole = strlen(p), cut = strcspn(p, "?#");
    const int decoded = percent_decode(p, cut, out, err, errn) == 0;
    if (decoded && ds_is_dir(out)) return 0;
    char other[256];
    if (percent_decode(p, whole, out, other, sizeof other) == 0 && ds_is_dir(out)) return 0;
    if (ds_is_dir(p)) {
        strcpy(out, p);
        return 0;
    }
    if (!decoded) return -1; /* the reason of the first decoding */
    return percent_decode(p, cut, out, err, errn);
}

char *ds_uri_to_path(const char *uri, char *err, size_t errn)
{
    if (!uri || !uri[0]) {
        ds_format(err, errn, "fmuResourceLocation is %s", uri ? "empty" : "NULL");
        return NULL;
    }
    char *out = malloc(strlen(uri) + 1);
    if (!out) {
        ds_format(err, errn, "out of memory");
        return NULL;
    }
    if (decode(uri, out, err, errn) != 0) {
        free(out);
        return NULL;
    }
    for (size_t n = strlen(out); n > 1 && out[n - 1] == '/'; --n) out[n - 1] = '\0';
    return out;
}

int ds_check_resources(const char *dir, char *err, size_t errn)
{
    static const char *const required[] = {RUNTIME_FILE, BOOT_MODULE ".py", DS_ENTRY_MODULE ".py",
                                           "slavemodule.txt", "drillstring_fmu.json",
                                           "drillstring/__init__.py", NULL};
    struct stat st;
    if (stat(dir, &st) != 0) {
        ds_format(err, errn, "resources folder '%s' does not exist (%s)", dir, strerror(errno));
        return -1;
    }
    if (!S_ISDIR(st.st_mode)) {
        ds_format(err, errn, "resources location '%s' is not a folder", dir);
        return -1;
    }
    if (access(dir, R_OK | X_OK) != 0) {
        ds_format(err, errn, "resources folder '%s' is not readable (%s)", dir, strerror(errno));
        return -1;
    }
    for (int i = 0; required[i]; ++i) {
        char *path = ds_strf("%s/%s", dir, required[i]);
        const int readable = path && access(path, R_OK) == 0;
        const int why = errno;
        free(path);
        if (!path) {
            ds_format(err, errn, "out of memory");
            return -1;
        }
        if (!readable) {
            ds_format(err, errn, "resources folder '%s' lacks a readable %s (%s): not the "
                      "unpacked resources of %s.fmu", dir, required[i], strerror(why),
                      DS_MODEL_IDENTIFIER);
            return -1;
        }
    }
    return 0;
}
