/* kollagen's generator, its hot paths compiled: the walk's draws and poses, the dead-reckoned
 * headings, a walk's grid cells, and the loop-closure search and sampler (studio.generator.walk and
 * studio.generator.loop_closures call them where this module was built; their numpy and Python code
 * is the path without a compiler and the reference the tests hold these functions to).
 *
 * Bit for bit the same as that code: the comparisons and the arithmetic are the same IEEE double
 * operations in the same order, log, sqrt, cos and sin are the C library's (those Python's math
 * calls), and the build turns floating-point contraction off (-ffp-contract=off: no fused
 * multiply-add where the Python code rounds twice) and GCC's built-in maths (-fno-builtin: no sincos
 * where Python calls cos and sin).
 *
 * sample(probs, uniforms, h, d, cached) -> (accepted, normals, h, d, cached, complete)
 *   The sampler alone (studio.generator.loop_closures._sample_python), for hits numpy found: each hit
 *   is decided by one uniform, in order; an accepted hit draws three normals (libstdc++'s polar
 *   method, one value cached between calls), which moves every later hit's uniform.
 *   probs     C-contiguous float64 buffer: each hit's probability, in visiting order
 *   uniforms  C-contiguous float64 buffer: the canonical doubles of the stream, from hit 0's on
 *   h, d      the next hit to decide and the offset of its uniform (hit h reads uniforms[h + d])
 *   cached    the normal distribution's cached value (None when it holds none)
 *   Returns the accepted hits (a bytearray of int64) and their normals (a bytearray of float64, three
 *   per hit), and the state after the last accepted hit: complete is False when the uniforms ran out
 *   before every hit was decided (call again with more uniforms from the returned state).
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

typedef struct {
    char *data;
    Py_ssize_t used, size;
} growable;

static int grow_append(growable *g, const void *item, Py_ssize_t n) {
    if (g->used + n > g->size) {
        Py_ssize_t size = g->size ? g->size : 1024;
        while (g->used + n > size) size *= 2;
        char *data = PyMem_Realloc(g->data, (size_t)size);
        if (data == NULL) {
            PyErr_NoMemory();
            return -1;
        }
        g->data = data;
        g->size = size;
    }
    memcpy(g->data + g->used, item, (size_t)n);
    g->used += n;
    return 0;
}

static int get_doubles(PyObject *obj, Py_buffer *view, const char *what) {
    if (PyObject_GetBuffer(obj, view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0) return -1;
    if (view->itemsize != (Py_ssize_t)sizeof(double) || view->format == NULL || strcmp(view->format, "d") != 0) {
        PyBuffer_Release(view);
        PyErr_Format(PyExc_TypeError, "%s must be a contiguous float64 buffer", what);
        return -1;
    }
    return 0;
}

/* One round of the polar method from uniform q: 0 with (returned, cached) and the next q, or -1
 * when it would read past n uniforms. */
static inline int polar(const double *u, Py_ssize_t n, Py_ssize_t *q, double *returned, double *kept) {
    double x, y, r2;
    Py_ssize_t i = *q;
    for (;;) {
        if (i + 1 >= n) return -1;
        x = 2.0 * u[i] - 1.0;
        y = 2.0 * u[i + 1] - 1.0;
        i += 2;
        r2 = x * x + y * y;
        if (!(r2 > 1.0 || r2 == 0.0)) break;
    }
    double mult = sqrt(-2.0 * log(r2) / r2);
    *returned = y * mult;
    *kept = x * mult;
    *q = i;
    return 0;
}

static PyObject *sample(PyObject *self, PyObject *args) {
    PyObject *probs_obj, *uniforms_obj, *cached_obj;
    Py_ssize_t h, d;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOnnO:sample", &probs_obj, &uniforms_obj, &h, &d, &cached_obj)) return NULL;
    int has_cached = cached_obj != Py_None;
    double cached = 0.0;
    if (has_cached) {
        cached = PyFloat_AsDouble(cached_obj);
        if (cached == -1.0 && PyErr_Occurred()) return NULL;
    }
    if (h < 0 || d < 0) {
        PyErr_SetString(PyExc_ValueError, "sample: h and d must be non-negative");
        return NULL;
    }
    Py_buffer pv, uv;
    if (get_doubles(probs_obj, &pv, "probs") < 0) return NULL;
    if (get_doubles(uniforms_obj, &uv, "uniforms") < 0) {
        PyBuffer_Release(&pv);
        return NULL;
    }
    const double *p = (const double *)pv.buf, *u = (const double *)uv.buf;
    const Py_ssize_t n_hits = pv.len / (Py_ssize_t)sizeof(double);
    const Py_ssize_t n_u = uv.len / (Py_ssize_t)sizeof(double);
    growable acc = {NULL, 0, 0}, nor = {NULL, 0, 0};
    int complete = 1, failed = 0;

    while (h < n_hits) {
        /* the first hit from h on accepted with offset d */
        Py_ssize_t e = h, stop = n_hits;
        if (stop + d > n_u) stop = n_u - d; /* hits whose uniforms are in the buffer */
        while (e < stop && !(p[e] > u[e + d])) e++;
        if (e >= stop) {
            if (stop < n_hits) complete = 0; /* the uniforms ran out: state stays at h, d */
            else h = n_hits;
            break;
        }
        Py_ssize_t q = e + d + 1; /* the normals start after the accepted hit's uniform */
        double v[3], keep = 0.0;
        int keeps;
        if (!has_cached) {
            if (polar(u, n_u, &q, &v[0], &v[1]) < 0 || polar(u, n_u, &q, &v[2], &keep) < 0) {
                complete = 0;
                break;
            }
            keeps = 1;
        } else {
            v[0] = cached;
            if (polar(u, n_u, &q, &v[1], &v[2]) < 0) {
                complete = 0;
                break;
            }
            keeps = 0;
        }
        int64_t index = (int64_t)e;
        failed = grow_append(&acc, &index, sizeof index) < 0 || grow_append(&nor, v, sizeof v) < 0;
        if (failed) break;
        has_cached = keeps;
        cached = keep;
        h = e + 1;
        d = q - e - 1;
    }

    PyBuffer_Release(&pv);
    PyBuffer_Release(&uv);
    PyObject *result = NULL;
    if (!failed) {
        PyObject *a = PyByteArray_FromStringAndSize(acc.data ? acc.data : "", acc.used);
        PyObject *b = PyByteArray_FromStringAndSize(nor.data ? nor.data : "", nor.used);
        PyObject *c = has_cached ? PyFloat_FromDouble(cached) : (Py_INCREF(Py_None), Py_None);
        if (a && b && c) result = Py_BuildValue("OOnnOO", a, b, h, d, c, complete ? Py_True : Py_False);
        Py_XDECREF(a);
        Py_XDECREF(b);
        Py_XDECREF(c);
    }
    PyMem_Free(acc.data);
    PyMem_Free(nor.data);
    return result;
}

/* std::mt19937 (MT19937, init_genrand seeding: what numpy's RandomState(seed) does too) and
 * libstdc++'s generate_canonical<double, 53> on its words (studio.generator.rng.canonical_doubles). */
enum { MT_N = 624, MT_M = 397 };

typedef struct {
    uint32_t mt[MT_N];
    uint32_t out[MT_N]; /* the tempered words of the current state */
    int i;              /* the next word of out */
} mt19937;

static void mt_seed(mt19937 *g, uint32_t seed) {
    g->mt[0] = seed;
    for (int i = 1; i < MT_N; i++) g->mt[i] = 1812433253U * (g->mt[i - 1] ^ (g->mt[i - 1] >> 30)) + (uint32_t)i;
    g->i = MT_N;
}

/* The next 624 words at once: the twist, then the tempering in a loop the compiler vectorises. */
static void mt_refill(mt19937 *g) {
    uint32_t *mt = g->mt, y;
    int k;
    for (k = 0; k < MT_N - MT_M; k++) {
        y = (mt[k] & 0x80000000U) | (mt[k + 1] & 0x7fffffffU);
        mt[k] = mt[k + MT_M] ^ (y >> 1) ^ ((0U - (y & 1U)) & 0x9908b0dfU);
    }
    for (; k < MT_N - 1; k++) {
        y = (mt[k] & 0x80000000U) | (mt[k + 1] & 0x7fffffffU);
        mt[k] = mt[k + (MT_M - MT_N)] ^ (y >> 1) ^ ((0U - (y & 1U)) & 0x9908b0dfU);
    }
    y = (mt[MT_N - 1] & 0x80000000U) | (mt[0] & 0x7fffffffU);
    mt[MT_N - 1] = mt[MT_M - 1] ^ (y >> 1) ^ ((0U - (y & 1U)) & 0x9908b0dfU);
    for (k = 0; k < MT_N; k++) {
        y = mt[k];
        y ^= y >> 11;
        y ^= (y << 7) & 0x9d2c5680U;
        y ^= (y << 15) & 0xefc60000U;
        y ^= y >> 18;
        g->out[k] = y;
    }
    g->i = 0;
}

static inline uint32_t mt_next(mt19937 *g) {
    if (g->i >= MT_N) mt_refill(g);
    return g->out[g->i++];
}

/* generate_canonical<double, 53> of two words: (lo + hi 2^32) / 2^64, a result of 1 made the largest
 * double below 1 (studio.generator.rng.canonical_doubles) */
static inline double canonical(uint32_t lo, uint32_t hi) {
    double v = (double)hi * 4294967296.0; /* exact */
    v += (double)lo;                      /* one rounding, as libstdc++'s sum */
    v *= 1.0 / 18446744073709551616.0;    /* exact: a power of two */
    return v < 0x1.fffffffffffffp-1 ? v : 0x1.fffffffffffffp-1;
}

/* A window of the stream's uniforms as their word pairs: uniform base + j is canonical(w[2 j],
 * w[2 j + 1]), j < len (the search compares most of them by their high word alone). */
typedef struct {
    mt19937 gen;
    uint32_t *w;
    Py_ssize_t cap, len, base;
} uniform_source;

/* Drop the uniforms before keep_from and copy new ones until the window holds those up to end
 * (exclusive) and is full; 0, or -1 with an exception set. */
static int source_fill(uniform_source *s, Py_ssize_t keep_from, Py_ssize_t end) {
    Py_ssize_t drop = keep_from - s->base;
    if (drop > 0) {
        memmove(s->w, s->w + 2 * drop, (size_t)(s->len - drop) * 2 * sizeof(uint32_t));
        s->len -= drop;
        s->base = keep_from;
    }
    if (end - s->base > s->cap) {
        Py_ssize_t cap = s->cap ? s->cap : 4096;
        while (cap < end - s->base) cap *= 2;
        uint32_t *w = PyMem_Realloc(s->w, (size_t)cap * 2 * sizeof(uint32_t));
        if (w == NULL) {
            PyErr_NoMemory();
            return -1;
        }
        s->w = w;
        s->cap = cap;
    }
    mt19937 *g = &s->gen;
    while (s->len < s->cap) {
        /* the pairs that lie whole in the tempered block, copied at once */
        Py_ssize_t pairs = (MT_N - g->i) / 2, room = s->cap - s->len;
        if (pairs > room) pairs = room;
        memcpy(s->w + 2 * s->len, g->out + g->i, (size_t)pairs * 2 * sizeof(uint32_t));
        g->i += (int)(2 * pairs);
        s->len += pairs;
        if (s->len < s->cap && g->i >= MT_N - 1) { /* a pair across two blocks (or none left) */
            s->w[2 * s->len] = mt_next(g);
            s->w[2 * s->len + 1] = mt_next(g);
            s->len++;
        }
    }
    return 0;
}

static int get_int64s(PyObject *obj, Py_buffer *view, const char *what) {
    if (PyObject_GetBuffer(obj, view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0) return -1;
    const char *f = view->format;
    if (view->itemsize != 8 || f == NULL || !(strcmp(f, "q") == 0 || strcmp(f, "l") == 0)) {
        PyBuffer_Release(view);
        PyErr_Format(PyExc_TypeError, "%s must be a contiguous int64 buffer", what);
        return -1;
    }
    return 0;
}

/* the first index in [lo, hi) whose value is >= v (values sorted) */
static inline Py_ssize_t lower_bound(const int64_t *a, Py_ssize_t lo, Py_ssize_t hi, int64_t v) {
    while (lo < hi) {
        Py_ssize_t mid = lo + (hi - lo) / 2;
        if (a[mid] < v) lo = mid + 1;
        else hi = mid;
    }
    return lo;
}

/* ------------------------------------------------------------------------------------------------
 * closures(qx, qy, col_start, col_y, col_m, x0, ylim, colbase, probs, before_query, seed, skip)
 *     -> (k, m, normals, used)
 *
 * The loop-closure search and the sampler in one pass, in kollagen's visiting order, without a list
 * of hits: for each query cell (qx[k], qy[k]) the same-cell check, then the discrete circle's columns
 * dx = -R..R, each visited dy = 0, 1, -1, 2, -2, ... The table's cells are in columns: column
 * c = x - x0 holds entries col_start[c] .. col_start[c + 1] - 1, sorted by y, each with its pose
 * col_m. A hit's probability is probs[rank + 1] (rank -1: the same cell; the circle rank of (dx, dy)
 * is colbase[dx + R] plus its place in the column); a NaN probability, or with before_query a table
 * pose not before the query (k <= m; the map grows with k, see column_index), is no candidate and
 * reads no uniform. Every candidate reads the
 * next uniform and is accepted when its probability exceeds it; an accepted one draws three normals
 * (the sampler above). The uniforms are those of std::mt19937(seed) from word skip on (the words
 * the stream's earlier draws read; uniforms are word pairs from there), decoded as they are needed.
 * Returns the accepted candidates' queries k and table poses m (bytearrays of int64), their normals
 * (float64, three each) and the uniforms used (two words each). The normal distribution starts
 * with no cached value, as each of kollagen's loop-closure searches does.
 */
typedef struct {
    uniform_source src;
    const double *probs;
    int has_cached;
    double cached;
    Py_ssize_t ui; /* the next uniform */
    growable k, m, nor;
} closure_state;

/* An accepted candidate (its uniform at st->ui): its three normals drawn, recorded; 0, or -1 with an
 * exception set. Out of line: about one candidate in 200 is accepted. The normals' uniforms are
 * decoded here, 64 at a time (a round of the polar method rejects about one pair in five). */
static __attribute__((noinline)) int accept(closure_state *st, int64_t k, int64_t m) {
    uniform_source *src = &st->src;
    double local[64], *u = local;
    Py_ssize_t n = 64;
    for (;;) {
        const Py_ssize_t first = st->ui + 1; /* the normals' first uniform */
        if (first + n > src->base + src->len && source_fill(src, st->ui, first + n) < 0) goto fail;
        const uint32_t *w = src->w + 2 * (first - src->base);
        for (Py_ssize_t j = 0; j < n; j++) u[j] = canonical(w[2 * j], w[2 * j + 1]);
        Py_ssize_t q = 0;
        double v[3], keep = 0.0;
        int ok;
        if (!st->has_cached) {
            ok = polar(u, n, &q, &v[0], &v[1]) == 0 && polar(u, n, &q, &v[2], &keep) == 0;
        } else {
            v[0] = st->cached;
            ok = polar(u, n, &q, &v[1], &v[2]) == 0;
        }
        if (!ok) { /* the normals read past the decoded uniforms: twice as many, and draw them again */
            double *more = PyMem_Malloc((size_t)(2 * n) * sizeof(double));
            if (more == NULL) {
                PyErr_NoMemory();
                goto fail;
            }
            if (u != local) PyMem_Free(u);
            u = more;
            n *= 2;
            continue;
        }
        if (u != local) PyMem_Free(u);
        if (grow_append(&st->k, &k, sizeof k) < 0 || grow_append(&st->m, &m, sizeof m) < 0 ||
            grow_append(&st->nor, v, sizeof v) < 0)
            return -1;
        st->has_cached = !st->has_cached;
        st->cached = keep;
        st->ui = first + q;
        return 0;
    }
fail:
    if (u != local) PyMem_Free(u);
    return -1;
}

/* The next uniform's words and the end of the window, kept in registers by the search's loop (the
 * state's ui is brought up to date only around the rare calls that move the window or accept). */
typedef struct {
    const uint32_t *w, *end;
} cursor;

static inline void cursor_load(cursor *c, const closure_state *st) {
    c->w = st->src.w + 2 * (st->ui - st->src.base);
    c->end = st->src.w + 2 * st->src.len;
}

static inline void cursor_store(const cursor *c, closure_state *st) {
    st->ui = st->src.base + (c->w - st->src.w) / 2;
}

/* No candidate (a NaN probability) in the thresholds of accept_below. */
#define NO_CANDIDATE INT64_MIN

/* The high word below which a uniform is sure to lie under probability p: with Q = p 2^32 (exact),
 * a uniform of high word hi lies in [hi, hi + 1] / 2^32, so it is below p when hi < ceil(Q) - 1 and
 * not when hi > ceil(Q) - 1; hi = ceil(Q) - 1 is decided on the decoded double. */
static int64_t accept_below(double p) {
    if (!(p == p)) return NO_CANDIDATE;
    const double q = p * 4294967296.0;
    if (!(q > 0.0)) return -1;                  /* never accepted */
    if (q > 4294967296.0) return 4294967296LL; /* always */
    return (int64_t)ceil(q) - 1;
}

/* One hit (query k, table pose m, probability index r): 0, or -1 with an exception set. A NaN
 * probability (kollagen's intra-agent offsets off the diagonals) is no candidate and reads no
 * uniform; decided with a select, not a branch. A candidate is accepted when its probability
 * exceeds its uniform: decided on the uniform's high word against the probability's threshold
 * (accept_below), on the uniform itself in the one case in 2^32 where the word cannot tell. */
static inline __attribute__((always_inline)) int candidate(closure_state *st, cursor *cur, const int64_t *thresholds,
                                                           int64_t k, int64_t m, Py_ssize_t r) {
    const int64_t t = thresholds[r];
    const int is_candidate = t != NO_CANDIDATE;
    if (cur->w >= cur->end) {
        cursor_store(cur, st);
        if (source_fill(&st->src, st->ui, st->ui + 1) < 0) return -1;
        cursor_load(cur, st);
    }
    const int64_t hi = cur->w[1];
    int accepted = hi < t;
    if (__builtin_expect(hi == t, 0)) accepted = st->probs[r] > canonical(cur->w[0], cur->w[1]);
    if (!accepted) {
        cur->w += 2 * is_candidate;
        return 0;
    }
    cursor_store(cur, st);
    const int rc = accept(st, k, m);
    cursor_load(cur, st);
    return rc;
}

/* The table's cells by column, and "how many of column c's entries lie below v": a binary search, or
 * where the table's bounding box is small next to the look-ups, a table of every column's counts at
 * every y. Column c's entries are y[col_start[c]] .. y[col_end[c] - 1], sorted, each with its pose
 * m[..]. The search of an agent's own cells (before_query) grows the map as kollagen does: the cells
 * first visited before query k are in it when k is searched, inserted one by one in their columns
 * (whose room col_start[c] .. col_start[c + 1] - 1 is their final size), so the cells it does not
 * know yet cost no look-up. */
typedef struct {
    const int64_t *col_start;
    Py_ssize_t *col_end;
    int64_t *y, *m;
    int32_t *dense; /* (H + 1) per column: the first entry with y >= ymin + yy, or NULL */
    int64_t ymin, height;
} column_index;

static inline Py_ssize_t below(const column_index *ix, int64_t c, int64_t v) {
    if (ix->dense != NULL) {
        int64_t yy = v - ix->ymin;
        if (yy <= 0) return ix->col_start[c];
        if (yy >= ix->height) return ix->col_end[c];
        return ix->dense[c * (ix->height + 1) + yy];
    }
    return lower_bound(ix->y, ix->col_start[c], ix->col_end[c], v);
}

/* The columns' ends, and the counts table where it pays (else ix->dense stays NULL), of the full
 * table col_y or, with grow, of an empty one with room for it; 0, or -1 with an exception set. */
static int index_columns(column_index *ix, const int64_t *col_y, Py_ssize_t n_cols, Py_ssize_t n_table,
                         Py_ssize_t lookups, int grow) {
    ix->dense = NULL;
    ix->col_end = PyMem_Malloc((size_t)(n_cols > 0 ? n_cols : 1) * sizeof(Py_ssize_t));
    if (ix->col_end == NULL) {
        PyErr_NoMemory();
        return -1;
    }
    for (Py_ssize_t c = 0; c < n_cols; c++) ix->col_end[c] = grow ? ix->col_start[c] : ix->col_start[c + 1];
    if (n_table == 0 || n_table >= INT32_MAX) return 0;
    int64_t ymin = col_y[0], ymax = col_y[0];
    for (Py_ssize_t j = 1; j < n_table; j++) {
        if (col_y[j] < ymin) ymin = col_y[j];
        if (col_y[j] > ymax) ymax = col_y[j];
    }
    int64_t height = ymax - ymin + 1;
    if (height > (1 << 24) || (double)n_cols * (double)(height + 1) > 8.0 * (double)lookups ||
        (double)n_cols * (double)(height + 1) > (double)(1 << 24))
        return 0;
    int32_t *dense = PyMem_Malloc((size_t)n_cols * (size_t)(height + 1) * sizeof(int32_t));
    if (dense == NULL) {
        PyErr_NoMemory();
        return -1;
    }
    for (Py_ssize_t c = 0; c < n_cols; c++) {
        Py_ssize_t j = ix->col_start[c], end = ix->col_end[c];
        int32_t *row = dense + c * (height + 1);
        for (int64_t yy = 0; yy <= height; yy++) {
            while (j < end && col_y[j] < ymin + yy) j++;
            row[yy] = (int32_t)j;
        }
    }
    ix->dense = dense;
    ix->ymin = ymin;
    ix->height = height;
    return 0;
}

/* Cell (y, m) into column c of a growing map (room left for it: see column_index). */
static void insert_cell(column_index *ix, int64_t c, int64_t y, int64_t m) {
    Py_ssize_t lo = ix->col_start[c], end = ix->col_end[c];
    Py_ssize_t at = lower_bound(ix->y, lo, end, y);
    memmove(ix->y + at + 1, ix->y + at, (size_t)(end - at) * sizeof(int64_t));
    memmove(ix->m + at + 1, ix->m + at, (size_t)(end - at) * sizeof(int64_t));
    ix->y[at] = y;
    ix->m[at] = m;
    ix->col_end[c] = end + 1;
    if (ix->dense != NULL) {
        int32_t *row = ix->dense + c * (ix->height + 1);
        for (int64_t yy = y - ix->ymin + 1; yy <= ix->height; yy++) row[yy]++;
    }
}

typedef struct {
    int64_t m;
    Py_ssize_t j;
} cell_by_pose; /* a growing map's cell j, first visited at pose m */

static int by_pose(const void *a, const void *b) {
    const cell_by_pose *p = a, *q = b;
    if (p->m != q->m) return p->m < q->m ? -1 : 1;
    return p->j < q->j ? -1 : p->j > q->j;
}

static PyObject *closures(PyObject *self, PyObject *args) {
    PyObject *o[8];
    Py_ssize_t x0, skip;
    long long seed;
    int before_query;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOOOOnOOOpLn:closures", &o[0], &o[1], &o[2], &o[3], &o[4], &x0, &o[5], &o[6],
                          &o[7], &before_query, &seed, &skip))
        return NULL;
    if (skip < 0) {
        PyErr_SetString(PyExc_ValueError, "closures: skip must be a number of words >= 0");
        return NULL;
    }
    static const char *names[] = {"qx", "qy", "col_start", "col_y", "col_m", "ylim", "colbase"};
    Py_buffer v[8];
    int got = 0;
    PyObject *result = NULL;
    closure_state st;
    memset(&st, 0, sizeof st);
    column_index ix;
    memset(&ix, 0, sizeof ix);
    unsigned char *live = NULL;
    int64_t *thresholds = NULL;
    cell_by_pose *order = NULL; /* a growing map's cells by pose */
    Py_ssize_t *col_of = NULL;  /* and each cell's column */
    int64_t *grown = NULL;
    /* the stream of std::mt19937(seed) (seed modulo 2**32, as C++ converts it), words before skip read */
    mt_seed(&st.src.gen, (uint32_t)((unsigned long long)seed & 0xffffffffULL));
    for (Py_ssize_t w = 0; w < skip; w++) (void)mt_next(&st.src.gen);
    for (; got < 7; got++)
        if (get_int64s(o[got], &v[got], names[got]) < 0) goto done;
    if (get_doubles(o[7], &v[7], "probs") < 0) goto done;
    got = 8;
    {
        const int64_t *qx = v[0].buf, *qy = v[1].buf, *col_start = v[2].buf, *col_y = v[3].buf, *col_m = v[4].buf;
        const int64_t *ylim = v[5].buf, *colbase = v[6].buf;
        const Py_ssize_t nq = v[0].len / 8, n_cols = v[2].len / 8 - 1, n_table = v[3].len / 8;
        const Py_ssize_t side = v[5].len / 8, R = (side - 1) / 2;
        const Py_ssize_t n_probs = v[7].len / 8;
        st.probs = v[7].buf;
        if (v[1].len != v[0].len || n_cols < 0 || v[4].len != v[3].len || side % 2 != 1 || v[6].len != v[5].len ||
            n_probs < 1) {
            PyErr_SetString(PyExc_ValueError, "closures: inconsistent lengths");
            goto done;
        }
        if (n_cols > 0 && col_start[n_cols] != n_table) {
            PyErr_SetString(PyExc_ValueError, "closures: col_start does not end at the table's length");
            goto done;
        }
        for (Py_ssize_t j = 0; j < side; j++)
            if (colbase[j] < 0 || colbase[j] + 2 * ylim[j] + 1 >= n_probs) {
                PyErr_SetString(PyExc_ValueError, "closures: probs shorter than the circle");
                goto done;
            }
        /* the columns of the circle with any candidate offset (kollagen's intra-agent search has none
         * in its dx = 0 column, where a walk along the grid has most of its cells) */
        live = PyMem_Malloc((size_t)side);
        if (live == NULL) {
            PyErr_NoMemory();
            goto done;
        }
        thresholds = PyMem_Malloc((size_t)n_probs * sizeof(int64_t));
        if (thresholds == NULL) {
            PyErr_NoMemory();
            goto done;
        }
        for (Py_ssize_t r = 0; r < n_probs; r++) thresholds[r] = accept_below(st.probs[r]);
        for (Py_ssize_t j = 0; j < side; j++) {
            live[j] = 0;
            for (int64_t r = colbase[j] + 1; r <= colbase[j] + 2 * ylim[j] + 1; r++)
                live[j] |= thresholds[r] != NO_CANDIDATE;
        }
        ix.col_start = col_start;
        const int grow = before_query;
        if (grow) { /* the map starts empty; its cells come in by their poses (sorted once) */
            grown = PyMem_Malloc((size_t)(2 * n_table + 1) * sizeof(int64_t));
            order = PyMem_Malloc((size_t)(n_table + 1) * sizeof(cell_by_pose));
            col_of = PyMem_Malloc((size_t)(n_table + 1) * sizeof(Py_ssize_t));
            if (grown == NULL || order == NULL || col_of == NULL) {
                PyErr_NoMemory();
                goto done;
            }
            ix.y = grown;
            ix.m = grown + n_table;
            for (Py_ssize_t c = 0; c < n_cols; c++)
                for (Py_ssize_t j = col_start[c]; j < col_start[c + 1]; j++) col_of[j] = c;
            for (Py_ssize_t j = 0; j < n_table; j++) order[j] = (cell_by_pose){col_m[j], j};
            qsort(order, (size_t)n_table, sizeof(cell_by_pose), by_pose);
        } else {
            ix.y = (int64_t *)col_y; /* read only: a full map never grows */
            ix.m = (int64_t *)col_m;
        }
        if (index_columns(&ix, col_y, n_cols, n_table, 3 * nq * side, grow) < 0) goto done;
        if (source_fill(&st.src, 0, 1) < 0) goto done;
        const int64_t *ty = ix.y, *tm = ix.m;
        const Py_ssize_t *col_end = ix.col_end;
        Py_ssize_t next_in = 0; /* the next cell of a growing map, in order */
        cursor cur;
        cursor_load(&cur, &st);
        for (Py_ssize_t k = 0; k < nq; k++) {
            const int64_t x = qx[k], y = qy[k];
            const int64_t c0 = x - x0;
            for (; grow && next_in < n_table && order[next_in].m < k; next_in++) { /* first seen before k */
                const Py_ssize_t j = order[next_in].j;
                insert_cell(&ix, col_of[j], col_y[j], col_m[j]);
            }
            /* the same-cell check comes first */
            if (c0 >= 0 && c0 < n_cols) {
                Py_ssize_t at = below(&ix, c0, y);
                if (at < col_end[c0] && ty[at] == y && candidate(&st, &cur, thresholds, k, tm[at], 0) < 0) goto done;
            }
            for (Py_ssize_t j = 0; j < side; j++) {
                const int64_t dx = (int64_t)j - R, c = c0 + dx;
                if (c < 0 || c >= n_cols || !live[j]) continue;
                if (col_start[c] == col_end[c]) continue;
                const int64_t yl = ylim[j];
                Py_ssize_t a = below(&ix, c, y - yl), b = below(&ix, c, y + yl + 1);
                if (a == b) continue;
                Py_ssize_t up = ix.dense != NULL ? below(&ix, c, y) : lower_bound(ty, a, b, y), dn = up - 1;
                const Py_ssize_t base = colbase[j] + 1; /* probs index of the column's dy = 0 */
                /* merge the rows above (dy >= 0, rising) and below (dy < 0, falling) by |dy|, the
                 * row above first on a tie: selects, not branches (the side taken is data) */
                while (up < b || dn >= a) {
                    const int64_t du = up < b ? ty[up] - y : INT64_MAX;
                    const int64_t dd = dn >= a ? y - ty[dn] : INT64_MAX;
                    const int take_up = du <= dd;
                    const Py_ssize_t at = take_up ? up : dn;
                    const Py_ssize_t r = take_up ? base + 2 * du - (du != 0) : base + 2 * dd;
                    up += take_up;
                    dn -= !take_up;
                    if (take_up && du == 0 && dx == 0) continue; /* the same cell, checked first */
                    if (candidate(&st, &cur, thresholds, k, tm[at], r) < 0) goto done;
                }
            }
        }
        cursor_store(&cur, &st);
        PyObject *ka = PyByteArray_FromStringAndSize(st.k.data ? st.k.data : "", st.k.used);
        PyObject *ma = PyByteArray_FromStringAndSize(st.m.data ? st.m.data : "", st.m.used);
        PyObject *na = PyByteArray_FromStringAndSize(st.nor.data ? st.nor.data : "", st.nor.used);
        if (ka && ma && na) result = Py_BuildValue("OOOn", ka, ma, na, st.ui);
        Py_XDECREF(ka);
        Py_XDECREF(ma);
        Py_XDECREF(na);
    }
done:
    for (int i = 0; i < got; i++) PyBuffer_Release(&v[i]);
    PyMem_Free(st.src.w);
    PyMem_Free(ix.dense);
    PyMem_Free(ix.col_end);
    PyMem_Free(live);
    PyMem_Free(thresholds);
    PyMem_Free(grown);
    PyMem_Free(order);
    PyMem_Free(col_of);
    PyMem_Free(st.k.data);
    PyMem_Free(st.m.data);
    PyMem_Free(st.nor.data);
    return result;
}

/* ------------------------------------------------------------------------------------------------
 * walk(seed, n_steps, frag, retro) -> (turns, n_pos, n_ang, words)
 *
 * kollagen's random walk draws from std::mt19937(seed), from its first word, in its order
 * (studio.generator.walk._walk_draws): per step one integer, uniform_int_distribution(-1, 1 + retro)
 * by Lemire's multiply-shift with rejection of the biased low products; then per sub-step one
 * normal_distribution round, whose returned value (y * mult) is the position normal and whose cached
 * one (x * mult) the angle normal. Returns the turns (int64), the normals (float64, frag per step)
 * and the words read.
 */
static PyObject *walk(PyObject *self, PyObject *args) {
    long long seed;
    Py_ssize_t n_steps, frag;
    int retro;
    (void)self;
    if (!PyArg_ParseTuple(args, "Lnnp:walk", &seed, &n_steps, &frag, &retro)) return NULL;
    if (n_steps < 0 || frag < 1 || n_steps > PY_SSIZE_T_MAX / 8 / frag) {
        PyErr_SetString(PyExc_ValueError, "walk: n_steps >= 0 and frag >= 1 expected");
        return NULL;
    }
    PyObject *turns = PyByteArray_FromStringAndSize(NULL, n_steps * 8);
    PyObject *npos = PyByteArray_FromStringAndSize(NULL, n_steps * frag * 8);
    PyObject *nang = PyByteArray_FromStringAndSize(NULL, n_steps * frag * 8);
    if (turns == NULL || npos == NULL || nang == NULL) {
        Py_XDECREF(turns);
        Py_XDECREF(npos);
        Py_XDECREF(nang);
        return NULL;
    }
    int64_t *t = (int64_t *)PyByteArray_AS_STRING(turns);
    double *pos = (double *)PyByteArray_AS_STRING(npos), *ang = (double *)PyByteArray_AS_STRING(nang);
    mt19937 g;
    mt_seed(&g, (uint32_t)((unsigned long long)seed & 0xffffffffULL));
    const uint64_t span = 3 + (uint64_t)retro;
    const uint32_t threshold = (uint32_t)((((uint64_t)1 << 32) - span) % span);
    long long words = 0;
    for (Py_ssize_t s = 0, j = 0; s < n_steps; s++) {
        uint64_t prod;
        do {
            prod = (uint64_t)mt_next(&g) * span;
            words++;
        } while ((uint32_t)prod < threshold);
        t[s] = (int64_t)(prod >> 32) - 1;
        for (Py_ssize_t f = 0; f < frag; f++, j++) {
            double x, y, r2;
            do {
                uint32_t w0 = mt_next(&g), w1 = mt_next(&g), w2 = mt_next(&g), w3 = mt_next(&g);
                words += 4;
                x = 2.0 * canonical(w0, w1) - 1.0;
                y = 2.0 * canonical(w2, w3) - 1.0;
                r2 = x * x + y * y;
            } while (r2 > 1.0 || r2 == 0.0);
            double mult = sqrt(-2.0 * log(r2) / r2);
            pos[j] = y * mult;
            ang[j] = x * mult;
        }
    }
    return Py_BuildValue("NNNL", turns, npos, nang, words);
}

/* ------------------------------------------------------------------------------------------------
 * trajectory(turns, npos, nang, frag, stepsize, std_pos, std_ang, th_tab, dx_tab, dy_tab, turn_tab)
 *     -> (x, y, theta, delta_theta, odom_pos, odom_ang)
 *
 * kollagen's walk from its draws (studio.generator.walk._random_walk): the heading in quarter turns
 * (C's truncating %), each sub-step a unit move along it (dx_tab, dy_tab by heading + 3), positions
 * (integer sums) * stepsize / frag, the stored heading th_tab[heading + 3]; the odometry's step
 * hypot(move) + std_pos * npos and turn turn_tab[turn + 1] + std_ang * nang on a step's first
 * sub-step, std_ang * nang on the others.
 */
static PyObject *trajectory(PyObject *self, PyObject *args) {
    PyObject *o[7];
    Py_ssize_t frag;
    double stepsize, std_pos, std_ang;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOOndddOOOO:trajectory", &o[0], &o[1], &o[2], &frag, &stepsize, &std_pos, &std_ang,
                          &o[3], &o[4], &o[5], &o[6]))
        return NULL;
    Py_buffer v[7];
    int got = 0;
    PyObject *out[6] = {NULL, NULL, NULL, NULL, NULL, NULL}, *result = NULL;
    if (get_int64s(o[0], &v[got], "turns") < 0) goto done;
    got++;
    if (get_doubles(o[1], &v[got], "npos") < 0) goto done;
    got++;
    if (get_doubles(o[2], &v[got], "nang") < 0) goto done;
    got++;
    if (get_doubles(o[3], &v[got], "th_tab") < 0) goto done;
    got++;
    if (get_int64s(o[4], &v[got], "dx_tab") < 0) goto done;
    got++;
    if (get_int64s(o[5], &v[got], "dy_tab") < 0) goto done;
    got++;
    if (get_doubles(o[6], &v[got], "turn_tab") < 0) goto done;
    got++;
    const Py_ssize_t n_steps = v[0].len / 8;
    if (frag < 1 || v[1].len != n_steps * frag * 8 || v[2].len != v[1].len || v[3].len != 7 * 8 || v[4].len != 7 * 8 ||
        v[5].len != 7 * 8 || v[6].len != 4 * 8) {
        PyErr_SetString(PyExc_ValueError, "trajectory: inconsistent lengths");
        goto done;
    }
    const int64_t *turns = v[0].buf, *dx_tab = v[4].buf, *dy_tab = v[5].buf;
    const double *npos = v[1].buf, *nang = v[2].buf, *th_tab = v[3].buf, *turn_tab = v[6].buf;
    const Py_ssize_t n_sub = n_steps * frag;
    for (Py_ssize_t s = 0; s < n_steps; s++)
        if (turns[s] < -1 || turns[s] > 2) {
            PyErr_SetString(PyExc_ValueError, "trajectory: a turn outside -1..2");
            goto done;
        }
    for (int i = 0; i < 6; i++) {
        out[i] = PyByteArray_FromStringAndSize(NULL, (i < 3 ? n_sub + 1 : n_sub) * 8);
        if (out[i] == NULL) goto done;
    }
    double *x = (double *)PyByteArray_AS_STRING(out[0]), *y = (double *)PyByteArray_AS_STRING(out[1]);
    double *theta = (double *)PyByteArray_AS_STRING(out[2]);
    int64_t *delta = (int64_t *)PyByteArray_AS_STRING(out[3]);
    double *opos = (double *)PyByteArray_AS_STRING(out[4]), *oang = (double *)PyByteArray_AS_STRING(out[5]);
    const double fr = (double)frag;
    int64_t t = 0, xi = 0, yi = 0;
    x[0] = (double)xi * stepsize / fr;
    y[0] = (double)yi * stepsize / fr;
    theta[0] = 0.0;
    for (Py_ssize_t s = 0; s < n_steps; s++) {
        t = (t + turns[s]) % 4;
        const int64_t dxi = dx_tab[t + 3], dyi = dy_tab[t + 3];
        const double ddx = (double)dxi * stepsize / fr, ddy = (double)dyi * stepsize / fr, step = hypot(ddx, ddy);
        for (Py_ssize_t f = 0; f < frag; f++) {
            const Py_ssize_t j = s * frag + f;
            xi += dxi;
            yi += dyi;
            x[j + 1] = (double)xi * stepsize / fr;
            y[j + 1] = (double)yi * stepsize / fr;
            theta[j + 1] = th_tab[t + 3];
            opos[j] = step + std_pos * npos[j];
            const double noise = std_ang * nang[j];
            delta[j] = f == 0 ? turns[s] : 0;
            oang[j] = f == 0 ? turn_tab[turns[s] + 1] + noise : noise;
        }
    }
    result = Py_BuildValue("OOOOOO", out[0], out[1], out[2], out[3], out[4], out[5]);
done:
    for (int i = 0; i < 6; i++) Py_XDECREF(out[i]);
    for (int i = 0; i < got; i++) PyBuffer_Release(&v[i]);
    return result;
}

/* (cos, sin): bytearrays of the C library's cos and sin of a[0..n) (Python's math.cos, math.sin),
 * or NULL with an exception set */
static PyObject *cos_sin_of(const double *a, Py_ssize_t n) {
    PyObject *co = PyByteArray_FromStringAndSize(NULL, n * 8);
    PyObject *si = PyByteArray_FromStringAndSize(NULL, n * 8);
    if (co == NULL || si == NULL) {
        Py_XDECREF(co);
        Py_XDECREF(si);
        return NULL;
    }
    double *c = (double *)PyByteArray_AS_STRING(co), *s = (double *)PyByteArray_AS_STRING(si);
    for (Py_ssize_t k = 0; k < n; k++) {
        c[k] = cos(a[k]);
        s[k] = sin(a[k]);
    }
    return Py_BuildValue("NN", co, si);
}

/* cos_sin(a) -> (cos, sin) of every entry of a */
static PyObject *cos_sin(PyObject *self, PyObject *args) {
    PyObject *obj;
    (void)self;
    if (!PyArg_ParseTuple(args, "O:cos_sin", &obj)) return NULL;
    Py_buffer v;
    if (get_doubles(obj, &v, "a") < 0) return NULL;
    PyObject *result = cos_sin_of(v.buf, v.len / 8);
    PyBuffer_Release(&v);
    return result;
}

/* ------------------------------------------------------------------------------------------------
 * headings(odom_ang) -> (theta, cos, sin)
 *
 * kollagen's dead-reckoned heading from 0 (studio.generator.walk._dead_reckon): after every edge
 * t = t + a, then t = t - floor((t + pi) / (2 pi)) * 2.0 * pi, in that order; theta holds the n + 1
 * headings, cos and sin (the C library's) those of theta[1:].
 */
static PyObject *headings(PyObject *self, PyObject *args) {
    PyObject *obj;
    (void)self;
    if (!PyArg_ParseTuple(args, "O:headings", &obj)) return NULL;
    Py_buffer v;
    if (get_doubles(obj, &v, "odom_ang") < 0) return NULL;
    const double *a = v.buf;
    const Py_ssize_t n = v.len / 8;
    PyObject *th = PyByteArray_FromStringAndSize(NULL, (n + 1) * 8), *trig = NULL, *result = NULL;
    if (th != NULL) {
        double *theta = (double *)PyByteArray_AS_STRING(th);
        const double pi = 3.141592653589793, two_pi = 2 * 3.141592653589793;
        double t = 0.0;
        theta[0] = 0.0;
        for (Py_ssize_t k = 0; k < n; k++) {
            t = t + a[k];
            t = t - floor((t + pi) / two_pi) * 2.0 * pi;
            theta[k + 1] = t;
        }
        trig = cos_sin_of(theta + 1, n);
        if (trig != NULL) result = Py_BuildValue("OOO", th, PyTuple_GET_ITEM(trig, 0), PyTuple_GET_ITEM(trig, 1));
    }
    Py_XDECREF(th);
    Py_XDECREF(trig);
    PyBuffer_Release(&v);
    return result;
}

/* ------------------------------------------------------------------------------------------------
 * cells(cx, cy, last, max_cells) -> (visits, x0, col_start, col_y) or None
 *
 * The distinct grid cells of a walk, each with the pose of its first (or with last, its last) visit,
 * in cell order (x, then y), laid out by column as closures() reads them: column x - x0 holds
 * entries col_start[x - x0] .. col_start[x - x0 + 1] - 1 (studio.generator.loop_closures._visits
 * and _columns). Through a grid over the walk's bounding box; None when that box has more than
 * max_cells cells.
 */
static PyObject *cells(PyObject *self, PyObject *args) {
    PyObject *ox, *oy;
    int last;
    Py_ssize_t max_cells;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOpn:cells", &ox, &oy, &last, &max_cells)) return NULL;
    Py_buffer vx, vy;
    if (get_int64s(ox, &vx, "cx") < 0) return NULL;
    if (get_int64s(oy, &vy, "cy") < 0) {
        PyBuffer_Release(&vx);
        return NULL;
    }
    PyObject *result = NULL;
    int32_t *grid = NULL;
    const int64_t *cx = vx.buf, *cy = vy.buf;
    const Py_ssize_t n = vx.len / 8;
    if (vy.len != vx.len || n == 0 || n >= INT32_MAX) {
        PyErr_SetString(PyExc_ValueError, "cells: cx and cy of one non-empty length expected");
        goto done;
    }
    int64_t xmin = cx[0], xmax = cx[0], ymin = cy[0], ymax = cy[0];
    for (Py_ssize_t k = 1; k < n; k++) {
        if (cx[k] < xmin) xmin = cx[k];
        if (cx[k] > xmax) xmax = cx[k];
        if (cy[k] < ymin) ymin = cy[k];
        if (cy[k] > ymax) ymax = cy[k];
    }
    const double w = (double)xmax - (double)xmin + 1.0, h = (double)ymax - (double)ymin + 1.0;
    if (w * h > (double)max_cells) {
        Py_INCREF(Py_None);
        result = Py_None;
        goto done;
    }
    const int64_t W = xmax - xmin + 1, H = ymax - ymin + 1;
    grid = PyMem_Malloc((size_t)(W * H) * sizeof(int32_t));
    if (grid == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    memset(grid, 0xff, (size_t)(W * H) * sizeof(int32_t)); /* -1: not visited */
    Py_ssize_t distinct = 0;
    for (Py_ssize_t k = 0; k < n; k++) {
        int32_t *g = grid + (cx[k] - xmin) * H + (cy[k] - ymin);
        if (*g < 0) distinct++;
        if (last || *g < 0) *g = (int32_t)k;
    }
    PyObject *visits = PyByteArray_FromStringAndSize(NULL, distinct * 8);
    PyObject *col_start = PyByteArray_FromStringAndSize(NULL, (W + 1) * 8);
    PyObject *col_y = PyByteArray_FromStringAndSize(NULL, distinct * 8);
    if (visits == NULL || col_start == NULL || col_y == NULL) {
        Py_XDECREF(visits);
        Py_XDECREF(col_start);
        Py_XDECREF(col_y);
        goto done;
    }
    int64_t *v = (int64_t *)PyByteArray_AS_STRING(visits), *cs = (int64_t *)PyByteArray_AS_STRING(col_start);
    int64_t *cyo = (int64_t *)PyByteArray_AS_STRING(col_y);
    Py_ssize_t j = 0;
    for (int64_t x = 0; x < W; x++) {
        cs[x] = j;
        const int32_t *row = grid + x * H;
        for (int64_t y = 0; y < H; y++)
            if (row[y] >= 0) {
                v[j] = row[y];
                cyo[j++] = y + ymin;
            }
    }
    cs[W] = j;
    result = Py_BuildValue("NLNN", visits, (long long)xmin, col_start, col_y);
done:
    PyMem_Free(grid);
    PyBuffer_Release(&vx);
    PyBuffer_Release(&vy);
    return result;
}

/* grid_cells(x, y, frag, stepsize) -> (cx, cy): C's round (half away from zero) of
 * x * frag / stepsize and of y's, as int64 (studio.generator.loop_closures._grid_cells) */
static PyObject *grid_cells(PyObject *self, PyObject *args) {
    PyObject *ox, *oy;
    double frag, stepsize;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOdd:grid_cells", &ox, &oy, &frag, &stepsize)) return NULL;
    Py_buffer v[2];
    if (get_doubles(ox, &v[0], "x") < 0) return NULL;
    if (get_doubles(oy, &v[1], "y") < 0) {
        PyBuffer_Release(&v[0]);
        return NULL;
    }
    PyObject *out[2] = {NULL, NULL}, *result = NULL;
    for (int i = 0; i < 2; i++) {
        const Py_ssize_t n = v[i].len / 8;
        const double *a = v[i].buf;
        out[i] = PyByteArray_FromStringAndSize(NULL, n * 8);
        if (out[i] == NULL) goto done;
        int64_t *c = (int64_t *)PyByteArray_AS_STRING(out[i]);
        for (Py_ssize_t k = 0; k < n; k++) {
            const double u = a[k] * frag / stepsize, t = trunc(u), f = u - t;
            c[k] = (int64_t)(t + (fabs(f) >= 0.5 ? (u > 0 ? 1.0 : -1.0) : 0.0));
        }
    }
    result = Py_BuildValue("OO", out[0], out[1]);
done:
    Py_XDECREF(out[0]);
    Py_XDECREF(out[1]);
    PyBuffer_Release(&v[0]);
    PyBuffer_Release(&v[1]);
    return result;
}

/* measurements(x_from, y_from, th_from, i_from, x_to, y_to, th_to, i_to, noise, std_pos, std_ang)
 *     -> (n, 3) float64 as a bytearray
 * Loop closures' measurements (studio.generator.loop_closures._measurements): pose i_to[e] of the
 * walk (x_to, y_to, th_to) in the frame of pose i_from[e] of (x_from, ...), in kollagen's order
 * (studio.core.geometry.relative_planar_pose: dx = xd c + yd s, dy = -xd s + yd c, the angle wrapped
 * as normalize_angle does), plus the normals noise[e] times the standard deviations. */
static PyObject *measurements(PyObject *self, PyObject *args) {
    PyObject *o[9];
    double sp, sa;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOOOOOOOOdd:measurements", &o[0], &o[1], &o[2], &o[3], &o[4], &o[5], &o[6], &o[7],
                          &o[8], &sp, &sa))
        return NULL;
    static const char *names[] = {"x_from", "y_from", "th_from", "i_from", "x_to", "y_to", "th_to", "i_to", "noise"};
    Py_buffer v[9];
    int got = 0;
    PyObject *result = NULL;
    for (; got < 9; got++) {
        const int index = got == 3 || got == 7;
        if ((index ? get_int64s(o[got], &v[got], names[got]) : get_doubles(o[got], &v[got], names[got])) < 0) goto done;
    }
    {
        const double *xf = v[0].buf, *yf = v[1].buf, *tf = v[2].buf, *xt = v[4].buf, *yt = v[5].buf, *tt = v[6].buf;
        const int64_t *jf = v[3].buf, *jt = v[7].buf;
        const double *noise = v[8].buf;
        const Py_ssize_t n = v[3].len / 8, nf = v[0].len / 8, nt = v[4].len / 8;
        if (v[1].len != v[0].len || v[2].len != v[0].len || v[5].len != v[4].len || v[6].len != v[4].len ||
            v[7].len != v[3].len || v[8].len != 3 * v[3].len) {
            PyErr_SetString(PyExc_ValueError, "measurements: inconsistent lengths");
            goto done;
        }
        for (Py_ssize_t e = 0; e < n; e++)
            if (jf[e] < 0 || jf[e] >= nf || jt[e] < 0 || jt[e] >= nt) {
                PyErr_SetString(PyExc_IndexError, "measurements: a pose index out of range");
                goto done;
            }
        result = PyByteArray_FromStringAndSize(NULL, 3 * n * 8);
        if (result == NULL) goto done;
        double *out = (double *)PyByteArray_AS_STRING(result);
        for (Py_ssize_t e = 0; e < n; e++) {
            const int64_t a = jf[e], b = jt[e];
            const double xdiff = xt[b] - xf[a], ydiff = yt[b] - yf[a];
            const double c = cos(tf[a]), sn = sin(tf[a]);
            const double dx = xdiff * c + ydiff * sn;
            const double dy = -xdiff * sn + ydiff * c;
            const double d = tt[b] - tf[a];
            const double dth = d - floor((d + Py_MATH_PI) / (2.0 * Py_MATH_PI)) * 2.0 * Py_MATH_PI;
            out[3 * e] = dx + noise[3 * e] * sp;
            out[3 * e + 1] = dy + noise[3 * e + 1] * sp;
            out[3 * e + 2] = dth + noise[3 * e + 2] * sa;
        }
    }
done:
    for (int i = 0; i < got; i++) PyBuffer_Release(&v[i]);
    return result;
}

static PyMethodDef methods[] = {
    {"sample", sample, METH_VARARGS, "Decide loop-closure hits in order (see the module's source)."},
    {"closures", closures, METH_VARARGS, "Search and sample loop closures in one pass (see the module's source)."},
    {"walk", walk, METH_VARARGS, "kollagen's random walk's draws (see the module's source)."},
    {"trajectory", trajectory, METH_VARARGS, "kollagen's walk from its draws (see the module's source)."},
    {"headings", headings, METH_VARARGS, "kollagen's dead-reckoned headings (see the module's source)."},
    {"cells", cells, METH_VARARGS, "A walk's distinct cells by column (see the module's source)."},
    {"cos_sin", cos_sin, METH_VARARGS, "The C library's cos and sin of every entry."},
    {"measurements", measurements, METH_VARARGS, "Loop closures' measurements (see the module's source)."},
    {"grid_cells", grid_cells, METH_VARARGS, "A walk's grid cells, rounded as C rounds (see the module's source)."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_sampler",
                                    "kollagen's generator, its hot paths compiled (see the module's source).", -1,
                                    methods};

PyMODINIT_FUNC PyInit__sampler(void) { return PyModule_Create(&module); }
