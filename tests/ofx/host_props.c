/* The test host's property sets and its OfxPropertySuiteV1. */
#include "ofx_host.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define HP_MAGIC 0x50524f50u /* "PROP" */

typedef struct hp_prop {
    char name[96];
    char type;
    int dim; /* 0: any */
    int plugin_writes;
    int count;
    union {
        int *i;
        double *d;
        char **s;
        void **p;
    } v;
} hp_prop;

struct OfxPropertySetStruct {
    uint32_t magic;
    char kind[48];
    hp_prop *props;
    int num, cap;
    void *owner;
};

OfxPropertySetHandle hp_check(OfxPropertySetHandle ps) { return ps && ps->magic == HP_MAGIC ? ps : NULL; }
void *hp_owner(OfxPropertySetHandle ps) { return hp_check(ps) ? ps->owner : NULL; }
void hp_set_owner(OfxPropertySetHandle ps, void *owner) { ps->owner = owner; }

static hp_prop *find(OfxPropertySetHandle ps, const char *name) {
    for (int i = 0; name && i < ps->num; i++)
        if (!strcmp(ps->props[i].name, name)) return &ps->props[i];
    return NULL;
}

static size_t elem_size(char type) {
    return type == 'i' ? sizeof(int) : type == 'd' ? sizeof(double) : sizeof(void *);
}

/* Make room for `count` values (zero-filled). */
static void resize(hp_prop *p, int count) {
    if (count <= p->count && p->v.p) return;
    size_t n = (size_t)(count > 0 ? count : 1);
    void *mem = calloc(n, elem_size(p->type));
    if (!mem) abort();
    if (p->v.p) {
        memcpy(mem, p->v.p, (size_t)p->count * elem_size(p->type));
        free(p->v.p);
    }
    p->v.p = (void **)mem;
    p->count = count;
}

void hp_declare(OfxPropertySetHandle ps, const char *name, char type, int dim, int plugin_writes) {
    if (find(ps, name)) return;
    if (ps->num == ps->cap) {
        ps->cap = ps->cap ? 2 * ps->cap : 16;
        ps->props = (hp_prop *)realloc(ps->props, (size_t)ps->cap * sizeof *ps->props);
        if (!ps->props) abort();
    }
    hp_prop *p = &ps->props[ps->num++];
    memset(p, 0, sizeof *p);
    snprintf(p->name, sizeof p->name, "%s", name);
    p->type = type;
    p->dim = dim;
    p->plugin_writes = plugin_writes;
    /* fixed dimensions always hold `dim` values (zeros, "" until set) */
    if (dim > 0) resize(p, dim);
    if (type == 's')
        for (int i = 0; i < p->count; i++) p->v.s[i] = strdup("");
}

OfxPropertySetHandle hp_new(const char *kind, const hp_schema *schema) {
    OfxPropertySetHandle ps = (OfxPropertySetHandle)calloc(1, sizeof *ps);
    if (!ps) abort();
    ps->magic = HP_MAGIC;
    snprintf(ps->kind, sizeof ps->kind, "%s", kind);
    for (const hp_schema *s = schema; s && s->name; s++) hp_declare(ps, s->name, s->type, s->dim, s->plugin_writes);
    return ps;
}

void hp_free(OfxPropertySetHandle ps) {
    if (!hp_check(ps)) return;
    for (int i = 0; i < ps->num; i++) {
        hp_prop *p = &ps->props[i];
        if (p->type == 's')
            for (int k = 0; k < p->count; k++) free(p->v.s[k]);
        free(p->v.p);
    }
    free(ps->props);
    ps->magic = 0;
    free(ps);
}

/* ---- the checks a plugin's calls go through ---------------------------- */
enum { FOR_GET = 0, FOR_SET = 1 };

static OfxStatus lookup(OfxPropertySetHandle ps, const char *name, char type, int index, int count, int how,
                        hp_prop **out) {
    *out = NULL;
    if (!hp_check(ps)) {
        host_violation("property call on a bad handle (%s)", name ? name : "(null)");
        return kOfxStatErrBadHandle;
    }
    if (!name) {
        host_violation("property name NULL on %s", ps->kind);
        return kOfxStatErrUnknown;
    }
    hp_prop *p = find(ps, name);
    if (!p) {
        /* Asking for a property an object lacks is how plugins probe for
         * optional features; setting one is a mistake. */
        if (how == FOR_SET) host_violation("set of unknown property %s on %s", name, ps->kind);
        return kOfxStatErrUnknown;
    }
    if (p->type != type) {
        host_violation("property %s on %s is of type '%c', accessed as '%c'", name, ps->kind, p->type, type);
        return kOfxStatErrValue;
    }
    if (how == FOR_SET && !p->plugin_writes) {
        host_violation("plugin set read-only property %s on %s", name, ps->kind);
        return kOfxStatErrValue;
    }
    if (index < 0 || count < 0) {
        host_violation("negative index/count for %s on %s", name, ps->kind);
        return kOfxStatErrBadIndex;
    }
    int last = index + (count > 0 ? count : 1) - 1;
    if (how == FOR_GET && last >= p->count) {
        host_violation("get of %s[%d] on %s which has %d values", name, last, ps->kind, p->count);
        return kOfxStatErrBadIndex;
    }
    if (how == FOR_SET && ((p->dim > 0 && last >= p->dim) || (p->dim == 0 && index > p->count))) {
        host_violation("set of %s[%d] on %s out of range", name, last, ps->kind);
        return kOfxStatErrBadIndex;
    }
    *out = p;
    return kOfxStatOK;
}

/* Room for value `index` (new strings are ""). */
static void grow(hp_prop *p, int index) {
    if (index < p->count) return;
    int old = p->count;
    resize(p, index + 1);
    if (p->type == 's')
        for (int i = old; i < p->count; i++) p->v.s[i] = strdup("");
}
static void store_i(hp_prop *p, int index, int v) {
    grow(p, index);
    p->v.i[index] = v;
}
static void store_d(hp_prop *p, int index, double v) {
    grow(p, index);
    p->v.d[index] = v;
}
static void store_p(hp_prop *p, int index, void *v) {
    grow(p, index);
    p->v.p[index] = v;
}
static void store_s(hp_prop *p, int index, const char *v) {
    grow(p, index);
    free(p->v.s[index]);
    p->v.s[index] = strdup(v ? v : "");
}

/* A variable-dimension property set with N values has exactly N. */
static void truncate_to(hp_prop *p, int count) {
    if (p->dim != 0 || count >= p->count) return;
    if (p->type == 's')
        for (int i = count; i < p->count; i++) free(p->v.s[i]);
    p->count = count;
}

#define SET_ONE(fname, ctype, tchar, storer)                                                                   \
    static OfxStatus fname(OfxPropertySetHandle ps, const char *name, int index, ctype value) {               \
        hp_prop *p;                                                                                             \
        OfxStatus st = lookup(ps, name, tchar, index, 1, FOR_SET, &p);                                          \
        if (st != kOfxStatOK) return st;                                                                       \
        storer(p, index, value);                                                                               \
        return kOfxStatOK;                                                                                     \
    }
SET_ONE(set_pointer, void *, 'p', store_p)
SET_ONE(set_string, const char *, 's', store_s)
SET_ONE(set_double, double, 'd', store_d)
SET_ONE(set_int, int, 'i', store_i)

#define SET_N(fname, ctype, tchar, storer)                                                                     \
    static OfxStatus fname(OfxPropertySetHandle ps, const char *name, int count, ctype values) {              \
        hp_prop *p;                                                                                             \
        OfxStatus st = lookup(ps, name, tchar, 0, count, FOR_SET, &p);                                          \
        if (st != kOfxStatOK) return st;                                                                       \
        if (count > 0 && !values) {                                                                             \
            host_violation("NULL values for %s", name);                                                        \
            return kOfxStatErrValue;                                                                           \
        }                                                                                                       \
        for (int i = 0; i < count; i++) storer(p, i, values[i]);                                               \
        truncate_to(p, count);                                                                                  \
        return kOfxStatOK;                                                                                     \
    }
SET_N(set_pointer_n, void *const *, 'p', store_p)
SET_N(set_string_n, const char *const *, 's', store_s)
SET_N(set_double_n, const double *, 'd', store_d)
SET_N(set_int_n, const int *, 'i', store_i)

#define GET_ONE(fname, ctype, tchar, member)                                                                   \
    static OfxStatus fname(OfxPropertySetHandle ps, const char *name, int index, ctype *value) {              \
        hp_prop *p;                                                                                             \
        if (!value) {                                                                                           \
            host_violation("NULL result pointer for %s", name ? name : "(null)");                              \
            return kOfxStatErrValue;                                                                           \
        }                                                                                                       \
        OfxStatus st = lookup(ps, name, tchar, index, 1, FOR_GET, &p);                                          \
        if (st != kOfxStatOK) return st;                                                                       \
        *value = p->v.member[index];                                                                           \
        return kOfxStatOK;                                                                                     \
    }
GET_ONE(get_pointer, void *, 'p', p)
GET_ONE(get_string, char *, 's', s)
GET_ONE(get_double, double, 'd', d)
GET_ONE(get_int, int, 'i', i)

#define GET_N(fname, ctype, tchar, member)                                                                     \
    static OfxStatus fname(OfxPropertySetHandle ps, const char *name, int count, ctype *values) {             \
        hp_prop *p;                                                                                             \
        OfxStatus st = lookup(ps, name, tchar, 0, count, FOR_GET, &p);                                          \
        if (st != kOfxStatOK) return st;                                                                       \
        if (count > 0 && !values) {                                                                             \
            host_violation("NULL result array for %s", name);                                                  \
            return kOfxStatErrValue;                                                                           \
        }                                                                                                       \
        for (int i = 0; i < count; i++) values[i] = p->v.member[i];                                            \
        return kOfxStatOK;                                                                                     \
    }
GET_N(get_pointer_n, void *, 'p', p)
GET_N(get_string_n, char *, 's', s)
GET_N(get_double_n, double, 'd', d)
GET_N(get_int_n, int, 'i', i)

static OfxStatus reset(OfxPropertySetHandle ps, const char *name) {
    if (!hp_check(ps)) {
        host_violation("propReset on a bad handle");
        return kOfxStatErrBadHandle;
    }
    hp_prop *p = find(ps, name);
    if (!p) return kOfxStatErrUnknown;
    if (!p->plugin_writes) {
        host_violation("propReset of read-only %s", name);
        return kOfxStatErrValue;
    }
    for (int i = 0; i < p->count; i++) {
        if (p->type == 's') {
            free(p->v.s[i]);
            p->v.s[i] = strdup("");
        } else if (p->type == 'i') {
            p->v.i[i] = 0;
        } else if (p->type == 'd') {
            p->v.d[i] = 0.0;
        } else {
            p->v.p[i] = NULL;
        }
    }
    return kOfxStatOK;
}

static OfxStatus dimension(OfxPropertySetHandle ps, const char *name, int *count) {
    if (!hp_check(ps)) {
        host_violation("propGetDimension on a bad handle");
        return kOfxStatErrBadHandle;
    }
    hp_prop *p = find(ps, name);
    if (!p) return kOfxStatErrUnknown;
    if (count) *count = p->count;
    return kOfxStatOK;
}

const OfxPropertySuiteV1 host_property_suite = {
    .propSetPointer = set_pointer,
    .propSetString = set_string,
    .propSetDouble = set_double,
    .propSetInt = set_int,
    .propSetPointerN = set_pointer_n,
    .propSetStringN = set_string_n,
    .propSetDoubleN = set_double_n,
    .propSetIntN = set_int_n,
    .propGetPointer = get_pointer,
    .propGetString = get_string,
    .propGetDouble = get_double,
    .propGetInt = get_int,
    .propGetPointerN = get_pointer_n,
    .propGetStringN = get_string_n,
    .propGetDoubleN = get_double_n,
    .propGetIntN = get_int_n,
    .propReset = reset,
    .propGetDimension = dimension,
};

/* ---- host-side access ---------------------------------------------------- */
static hp_prop *host_prop(OfxPropertySetHandle ps, const char *name, char type) {
    hp_prop *p = find(ps, name);
    if (!p) {
        hp_declare(ps, name, type, 0, 0);
        p = find(ps, name);
    }
    if (p->type != type) {
        fprintf(stderr, "test host bug: %s is '%c', not '%c'\n", name, p->type, type);
        abort();
    }
    return p;
}
void hp_set_i(OfxPropertySetHandle ps, const char *name, int index, int v) { store_i(host_prop(ps, name, 'i'), index, v); }
void hp_set_d(OfxPropertySetHandle ps, const char *name, int index, double v) {
    store_d(host_prop(ps, name, 'd'), index, v);
}
void hp_set_s(OfxPropertySetHandle ps, const char *name, int index, const char *v) {
    store_s(host_prop(ps, name, 's'), index, v);
}
void hp_set_p(OfxPropertySetHandle ps, const char *name, int index, void *v) {
    store_p(host_prop(ps, name, 'p'), index, v);
}

static hp_prop *peek(OfxPropertySetHandle ps, const char *name, char type, int index) {
    hp_prop *p = hp_check(ps) ? find(ps, name) : NULL;
    return p && p->type == type && index >= 0 && index < p->count ? p : NULL;
}
int hp_i(OfxPropertySetHandle ps, const char *name, int index) {
    hp_prop *p = peek(ps, name, 'i', index);
    return p ? p->v.i[index] : 0;
}
double hp_d(OfxPropertySetHandle ps, const char *name, int index) {
    hp_prop *p = peek(ps, name, 'd', index);
    return p ? p->v.d[index] : 0.0;
}
const char *hp_s(OfxPropertySetHandle ps, const char *name, int index) {
    hp_prop *p = peek(ps, name, 's', index);
    return p ? p->v.s[index] : "";
}
void *hp_p(OfxPropertySetHandle ps, const char *name, int index) {
    hp_prop *p = peek(ps, name, 'p', index);
    return p ? p->v.p[index] : NULL;
}
int hp_count(OfxPropertySetHandle ps, const char *name) {
    hp_prop *p = hp_check(ps) ? find(ps, name) : NULL;
    return p ? p->count : -1;
}
int hp_has_string(OfxPropertySetHandle ps, const char *name, const char *value) {
    hp_prop *p = hp_check(ps) ? find(ps, name) : NULL;
    if (!p || p->type != 's') return 0;
    for (int i = 0; i < p->count; i++)
        if (!strcmp(p->v.s[i], value)) return 1;
    return 0;
}

/* ---- statistics ----------------------------------------------------------- */
host_stats host_st;

void host_violation(const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(host_st.last_violation, sizeof host_st.last_violation, fmt, ap);
    va_end(ap);
    __atomic_add_fetch(&host_st.violations, 1, __ATOMIC_SEQ_CST);
}
