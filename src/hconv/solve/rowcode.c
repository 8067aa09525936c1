/* hconv.solve.rowcode: the compiled engine's row code, one fused pass per row.
 *
 * What it computes and what it leaves is hconv.solve.compiled's docstring; this file is its
 * arithmetic. Every operation is the numpy engine's (hconv.kernels.linsolve, .spectrum, .metrics,
 * hconv.solve.blocks), written in the same order with the same parentheses, so that `exact`'s
 * omega, cond and every status are the same bits; only the refinement steps and the residual's
 * norms multiply by reciprocals where the numpy engine divides (rowmath.h says where), as
 * refined's omega and the residual are within 2 eps of the numpy engine's, not its bits. It must be compiled so that it rounds as
 * written (setup.py): no contraction into fused multiply-adds (-ffp-contract=off) and no
 * fast-math; -fno-math-errno and -fno-trapping-math only let the compiler vectorise sqrt and
 * turn branches into selects, which changes no result. The one fused multiply-add is the
 * residual's explicit fma() (chunk_body), the exact error of a product as Dekker's splits give it.
 * A row this code cannot settle is marked fallback and converted by the numpy engine.
 *
 * pmin and pmax keep the first argument unless the second compares smaller or greater (as
 * Python's min and max, which the row code was first written with); where a NaN makes them
 * differ from numpy's, the row is not finite and falls back either way.
 *
 * Shapes, as hconv.solve.convert's internal layout: I is (k, N) in its form's value order (six
 * numbers xx yy zz xy xz yz, or nine row-major), H (3, N) [kg m^2/s], any strides; outputs
 * contiguous: w (N, 3) [rad/s], cond, code (uint8), residual, fallback (bool) (N,).
 */
#define PY_SSIZE_T_CLEAN
#ifndef NPY_NO_DEPRECATED_API
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#endif
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <numpy/arrayobject.h>
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
#include <immintrin.h>
#endif
#if defined(__linux__)
#include <sys/mman.h>
#endif

#include "rowmath.h" /* the chunk code; this file: its versions and the Python functions */

/* chunk_body compiled once per instruction set: wider vectors where the CPU has them, and fma
 * where it has that, chosen when the module loads (an x86-64 wheel must run on any x86-64).
 * More rows at once, the same operations on each, so the same bits; no multiply-add is fused but
 * the residual's explicit fma(). */
typedef void (*ChunkFn)(const Job *, Chunk *restrict, npy_intp, int);
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
/* each version's streaming stores (StreamFn), a line at a time */
__attribute__((target("avx512f"))) static void stream_avx512(void *restrict dst, const void *restrict src, size_t bytes)
{
    for (size_t i = 0; i < bytes; i += 64)
        _mm512_stream_si512((void *)((char *)dst + i), _mm512_loadu_si512((const char *)src + i));
}
__attribute__((target("avx2"))) static void stream_avx2(void *restrict dst, const void *restrict src, size_t bytes)
{
    for (size_t i = 0; i < bytes; i += 32)
        _mm256_stream_si256((__m256i *)((char *)dst + i), _mm256_loadu_si256((const __m256i *)((const char *)src + i)));
}
static void stream_sse2(void *restrict dst, const void *restrict src, size_t bytes)
{
    for (size_t i = 0; i < bytes; i += 16)
        _mm_stream_si128((__m128i *)((char *)dst + i), _mm_loadu_si128((const __m128i *)((const char *)src + i)));
}
static void store_fence(void) { _mm_sfence(); }
__attribute__((target("avx512f,fma"))) NOINLINE static void chunk_avx512(const Job *jb, Chunk *restrict s,
                                                                          npy_intp start, int m)
{
    chunk_body(jb, s, start, m, 1, jb->stream ? stream_avx512 : NULL);
}
__attribute__((target("avx2,fma"))) NOINLINE static void chunk_avx2(const Job *jb, Chunk *restrict s, npy_intp start,
                                                                   int m)
{
    chunk_body(jb, s, start, m, 1, jb->stream ? stream_avx2 : NULL);
}
NOINLINE static void chunk_plain(const Job *jb, Chunk *restrict s, npy_intp start, int m)
{
    chunk_body(jb, s, start, m, 0, jb->stream ? stream_sse2 : NULL);
}
/* the versions this CPU runs, the first the one used */
static int kernels_of_cpu(const char *names[3], ChunkFn fns[3])
{
    int k = 0;
    __builtin_cpu_init();
    if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("fma"))
        names[k] = "avx512f,fma", fns[k++] = chunk_avx512;
    if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma"))
        names[k] = "avx2,fma", fns[k++] = chunk_avx2;
    names[k] = "default", fns[k++] = chunk_plain;
    return k;
}
#else
/* no streaming stores here: every chunk is stored as it is computed */
static void store_fence(void) {}
NOINLINE static void chunk_plain(const Job *jb, Chunk *restrict s, npy_intp start, int m)
{
#if defined(FP_FAST_FMA) /* fma is an instruction on this target (aarch64, or x86 built for one with it) */
    chunk_body(jb, s, start, m, 1, NULL);
#else
    chunk_body(jb, s, start, m, 0, NULL);
#endif
}
static int kernels_of_cpu(const char *names[3], ChunkFn fns[3])
{
    names[0] = "default", fns[0] = chunk_plain;
    return 1;
}
#endif
static ChunkFn convert_chunk;

static int get(PyObject *c, const char *name, double *out)
{
    PyObject *v = PyDict_GetItemString(c, name);
    if (!v) {
        PyErr_Format(PyExc_KeyError, "rowcode.configure: %s missing", name);
        return -1;
    }
    *out = PyFloat_AsDouble(v);
    return PyErr_Occurred() ? -1 : 0;
}

static int configure_from(PyObject *c)
{
    double steps, refine_steps, codes[5];
    if (get(c, "SPLIT", &K.split) || get(c, "SINGULAR_LIMIT", &K.singular_limit) || get(c, "GRID", &K.grid) ||
        get(c, "SAFE", &K.safe) || get(c, "STOP", &K.stop) || get(c, "TINY", &K.tiny) || get(c, "S0", &K.s0) ||
        get(c, "S1", &K.s1) || get(c, "S2", &K.s2) || get(c, "S3", &K.s3) || get(c, "S4", &K.s4) ||
        get(c, "ROOT_RANGE", &K.root_range) || get(c, "SYMMETRY_RTOL", &K.symmetry_rtol) ||
        get(c, "TRIANGLE_RTOL", &K.triangle_rtol) || get(c, "ILL_CONDITIONED_TOL", &K.ill_tol) ||
        get(c, "EPS", &K.eps) || get(c, "SQRT_EPS", &K.sqrt_eps) || get(c, "MAX", &K.max) ||
        get(c, "ROOT_NEWTON_STEPS", &steps) || get(c, "MAX_REFINE_STEPS", &refine_steps) ||
        get(c, "OK", &codes[0]) || get(c, "SINGULAR", &codes[1]) || get(c, "NOT_PHYSICAL", &codes[2]) ||
        get(c, "ILL_CONDITIONED", &codes[3]) || get(c, "INACCURATE", &codes[4]))
        return -1;
    if (steps != NEWTON_STEPS) {
        PyErr_Format(PyExc_ValueError, "rowcode.configure: ROOT_NEWTON_STEPS is %g; this build has %d", steps,
                     NEWTON_STEPS);
        return -1;
    }
    K.max_refine_steps = (int)refine_steps;
    K.inv_safe = 1.0 / K.safe;
    K.inv_root_range = 1.0 / K.root_range;
    K.ok = codes[0], K.singular = codes[1], K.not_physical = codes[2];
    K.ill_conditioned = codes[3], K.inaccurate = codes[4];
    K.ready = 1;
    return 0;
}

static PyObject *configure(PyObject *self, PyObject *args)
{
    PyObject *c;
    if (!PyArg_ParseTuple(args, "O!", &PyDict_Type, &c))
        return NULL;
    if (configure_from(c) < 0)
        return NULL;
    Py_RETURN_NONE;
}

static int check(PyArrayObject *a, const char *name, int ndim, npy_intp d0, npy_intp d1, int type, int writable)
{
    if (PyArray_NDIM(a) != ndim || PyArray_TYPE(a) != type || PyArray_DIM(a, 0) != d0 ||
        (ndim == 2 && PyArray_DIM(a, 1) != d1)) {
        PyErr_Format(PyExc_ValueError, "rowcode.convert: %s has the wrong shape or dtype", name);
        return -1;
    }
    if (writable && !(PyArray_IS_C_CONTIGUOUS(a) && PyArray_ISWRITEABLE(a))) {
        PyErr_Format(PyExc_ValueError, "rowcode.convert: %s must be contiguous and writable", name);
        return -1;
    }
    return 0;
}

/* A large call's rows are shared between its caller and the threads serving (serve()), which stay
 * in C between calls, spinning, for a short while after their last block: the call after is
 * picked up at once, where a thread woken through Python cost a wake-up of the system's and the
 * GIL (tens of microseconds; docs/engines.md). A thread that is not serving converts nothing and
 * is owed nothing: the caller takes every block no other thread takes.
 *
 * The post of the call being converted is one set of statics, written only by its caller (the
 * one that holds `owned`). The word holds the post's generation (high 32 bits) and its next
 * block (low 32 bits): a thread takes a block by a compare-and-swap of the word it read to the
 * next block, and only then reads or writes a row. A swap from a word of an earlier generation
 * fails, so that a thread that read an earlier post, however late it comes, touches no row of
 * the arrays of a call that has returned. While a caller writes its post the word's block is
 * BUSY, and a thread that read the post while it changed finds the word changed (seqlock
 * order: the BUSY store, then the post; a reader: the word, the post, then the word again by
 * its swap). After each block a thread adds its rows to the rows done with release order, so
 * that the caller, which reads them with acquire order, sees every output of those rows
 * written; every block of a call is done before its caller returns, so that no thread adds to
 * the counts of the next. */
typedef struct {
    Job jb;
    npy_intp n, size;
    uint32_t blocks;
} Post;
#define BUSY 0xFFFFFFFFu
/* each on a cache line of its own: the word, written at every block taken, and the counts, at
 * every block done, would otherwise make every thread's copy of the post a miss */
#if defined(_MSC_VER)
#define LINE __declspec(align(64))
#else
#define LINE __attribute__((aligned(64)))
#endif
static LINE Post post;
static LINE uint64_t word;
static LINE npy_int64 rows_done;
static npy_int64 rows_lost;
static LINE int owned;
static int serving;
static int pool_lock, reaping; /* outputs()'s pool and whether its thread runs, below */

#if defined(_MSC_VER)
#include <intrin.h>
#define WIN32_LEAN_AND_MEAN
#define NOMINMAX
#include <windows.h>
static uint64_t load_word(void) { return (uint64_t)_InterlockedCompareExchange64((volatile __int64 *)&word, 0, 0); }
static void store_word(uint64_t v) { _InterlockedExchange64((volatile __int64 *)&word, (__int64)v); }
static int swap_word(uint64_t seen, uint64_t v)
{
    return (uint64_t)_InterlockedCompareExchange64((volatile __int64 *)&word, (__int64)v, (__int64)seen) == seen;
}
static void add(npy_int64 *c, npy_int64 v) { _InterlockedExchangeAdd64((volatile __int64 *)c, v); }
static npy_int64 read_count(npy_int64 *c) { return _InterlockedCompareExchange64((volatile __int64 *)c, 0, 0); }
static void set_count(npy_int64 *c, npy_int64 v) { _InterlockedExchange64((volatile __int64 *)c, v); }
static int take_slot(int *flag) { return _InterlockedCompareExchange((volatile long *)flag, 1, 0) == 0; }
static void give_slot(int *flag) { _InterlockedExchange((volatile long *)flag, 0); }
static void add_int(int *c, int v) { _InterlockedExchangeAdd((volatile long *)c, v); }
static int read_int(int *c) { return _InterlockedCompareExchange((volatile long *)c, 0, 0); }
static void fence(void) { MemoryBarrier(); }
static void relax(void) { YieldProcessor(); }
static void yield_core(void) { SwitchToThread(); }
static double seconds(void)
{
    LARGE_INTEGER t, f;
    QueryPerformanceCounter(&t), QueryPerformanceFrequency(&f);
    return (double)t.QuadPart / (double)f.QuadPart;
}
static void on_fork(void) {}
#else
#include <pthread.h>
#include <sched.h>
#include <time.h>
static uint64_t load_word(void) { return __atomic_load_n(&word, __ATOMIC_ACQUIRE); }
static void store_word(uint64_t v) { __atomic_store_n(&word, v, __ATOMIC_RELEASE); }
static int swap_word(uint64_t seen, uint64_t v)
{
    return __atomic_compare_exchange_n(&word, &seen, v, 0, __ATOMIC_ACQ_REL, __ATOMIC_ACQUIRE);
}
static void add(npy_int64 *c, npy_int64 v) { __atomic_fetch_add(c, v, __ATOMIC_RELEASE); }
static npy_int64 read_count(npy_int64 *c) { return __atomic_load_n(c, __ATOMIC_ACQUIRE); }
static void set_count(npy_int64 *c, npy_int64 v) { __atomic_store_n(c, v, __ATOMIC_RELAXED); }
static int take_slot(int *flag)
{
    int free_ = 0;
    return __atomic_compare_exchange_n(flag, &free_, 1, 0, __ATOMIC_ACQUIRE, __ATOMIC_RELAXED);
}
static void give_slot(int *flag) { __atomic_store_n(flag, 0, __ATOMIC_RELEASE); }
static void add_int(int *c, int v) { __atomic_fetch_add(c, v, __ATOMIC_RELAXED); }
static int read_int(int *c) { return __atomic_load_n(c, __ATOMIC_RELAXED); }
/* orders the BUSY store before the post's writes, and a reader's reads of the post before its swap */
static void fence(void) { __atomic_thread_fence(__ATOMIC_SEQ_CST); }
static void relax(void)
{
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#elif defined(__aarch64__)
    __asm__ __volatile__("yield");
#endif
}
static void yield_core(void) { sched_yield(); }
/* A child forked while a thread of its parent held the post or served has neither thread; the
 * post of a call its parent was converting would still offer blocks, to be written into arrays
 * no caller waits for, and counted in the child's next call: the post is retired (BUSY in a new
 * generation). The child has one thread here. */
static void pool_fork_prepare(void), pool_fork_parent(void), pool_forked(void); /* below */
static void forked(void)
{
    owned = 0, serving = 0;
    word = (((word >> 32) + 1) << 32) | BUSY;
    pool_forked();
}
static void on_fork(void) { pthread_atfork(pool_fork_prepare, pool_fork_parent, forked); }
static double seconds(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}
#endif
/* How many times a thread that waits (a caller for the last blocks of other threads, a serving
 * thread for the next call) spins before it gives its core away between looks: a thread put to
 * sleep took a wake-up of the system's (tens of microseconds) to learn what it waited for. */
#define SPINS 4096

/* The memory of the outputs of large calls (outputs()): a numpy memory handler whose blocks start
 * on cache lines, so that whole chunks can be streamed to them, and which keeps the blocks of at
 * least POOL_MIN bytes that numpy frees, up to POOL_MAX bytes and POOL_SLOTS blocks, for the next
 * calls. Fresh memory costs a page fault and the system's zeroing of each page at its first
 * store; a call in a loop, whose last result the caller has dropped, writes to memory already
 * mapped instead (docs/engines.md). Every block starts HEAD bytes after a header that holds its
 * size and where it came from: a block of POOL_MIN bytes or more is a mapping of its own, asked
 * for huge pages as numpy asks for its own, and goes back to the system whole when it is given
 * back (so that a kept block never fragments the C library's heap); a smaller one comes from the
 * C library. A request takes the smallest kept block that holds it and is at most twice its size
 * (a loop's sizes vary); it comes back whole. A kept block is given back once two calls of
 * outputs() have left it unused (a loop of one or two kinds of call keeps what it dropped last,
 * not older blocks), and POOL_IDLE seconds after it was kept, by a thread of the pool's own,
 * however the program goes on; release() gives back every block kept, and a forked child starts
 * with none. Arrays made with it are ordinary ndarrays that own their data: numpy remembers each
 * array's handler and frees its data through it. Every entry point takes the pool's lock (a spin
 * for a few comparisons: blocks are given back after it is let go). Without POSIX threads and
 * mappings (MSVC) nothing is kept: every block is the C library's. */
#define POOL_MIN ((size_t)4 << 20)
#define POOL_MAX ((size_t)128 << 20)
#define POOL_SLOTS 16
#define POOL_IDLE 1.0
#define HEAD 64
typedef struct {
    size_t size; /* the bytes after the header */
    int mapped;  /* a mapping of its own (else the C library's) */
} Head;
typedef struct {
    char *at;
    size_t size;
    double since;    /* when it was kept */
    npy_uint64 call; /* outputs()'s calls when it was kept */
} Block;
static Block kept[POOL_SLOTS];
static int nkept;
static size_t kept_bytes;
static npy_uint64 calls;
static npy_int64 pool_reused, pool_fresh;

static void pool_enter(void)
{
    for (unsigned long spins = 0; !take_slot(&pool_lock); spins++)
        if (spins < SPINS)
            relax();
        else
            yield_core();
}
static void pool_leave(void) { give_slot(&pool_lock); }

static Head *head_of(void *at) { return (Head *)((char *)at - HEAD); }

/* a block gone back to where it came from */
static void let_go(void *at)
{
    Head *h = head_of(at);
#if !defined(_MSC_VER)
    if (h->mapped) {
        munmap(h, h->size + HEAD);
        return;
    }
#endif
    free(h);
}

/* moves the kept blocks kept before `before`, or left unused by two calls (`every`: all), into
 * `out`, to be let go once the lock is; returns how many. The lock held. */
static int pool_expire(double before, int every, Block out[POOL_SLOTS])
{
    int k = 0, n = 0;
    for (int i = 0; i < nkept; i++)
        if (every || kept[i].since < before || kept[i].call + 2 < calls)
            out[n++] = kept[i], kept_bytes -= kept[i].size;
        else
            kept[k++] = kept[i];
    nkept = k;
    return n;
}
static void let_go_all(Block *out, int n)
{
    for (int i = 0; i < n; i++)
        let_go(out[i].at);
}
/* pool_expire under the lock, then the blocks let go */
static void give_back(double before, int every)
{
    Block out[POOL_SLOTS];
    pool_enter();
    int n = pool_expire(before, every, out);
    pool_leave();
    let_go_all(out, n);
}

#if defined(_MSC_VER)
static int start_reaper(void) { return -1; }
#else
static void snooze(double s)
{
    struct timespec t = {(time_t)s, (long)((s - (double)(time_t)s) * 1e9)};
    nanosleep(&t, NULL);
}
/* the pool's thread: gives back each kept block POOL_IDLE after it was kept, and ends when none
 * is left (the next block kept starts another) */
static void *reaper(void *arg)
{
    (void)arg;
    for (;;) {
        Block out[POOL_SLOTS];
        pool_enter();
        double now = seconds(), first = INFINITY;
        int n = pool_expire(now - POOL_IDLE, 0, out);
        for (int i = 0; i < nkept; i++)
            first = pmin(first, kept[i].since);
        if (nkept == 0)
            reaping = 0;
        pool_leave();
        let_go_all(out, n);
        if (first == INFINITY)
            return NULL;
        snooze(first + POOL_IDLE - now + 0.001);
    }
}
static int start_reaper(void)
{
    pthread_t t;
    pthread_attr_t a;
    if (pthread_attr_init(&a))
        return -1;
    pthread_attr_setdetachstate(&a, PTHREAD_CREATE_DETACHED);
    int failed = pthread_create(&t, &a, reaper, NULL);
    pthread_attr_destroy(&a);
    return failed ? -1 : 0;
}
/* fork: the parent's pool is held across it, so that the child finds it whole, not half changed
 * by the parent's reaper; the child, which has no reaper, lets every kept block go (munmap, which
 * a child may call however many threads its parent had) */
static void pool_fork_prepare(void) { pool_enter(); }
static void pool_fork_parent(void) { pool_leave(); }
static void pool_forked(void)
{
    for (int i = 0; i < nkept; i++)
        let_go(kept[i].at); /* kept blocks are all mappings */
    nkept = 0, kept_bytes = 0, reaping = 0;
    pool_lock = 0;
}
#endif

/* a new block of `size` bytes after its header; NULL if there is no memory */
static void *new_block(size_t size)
{
    Head *h = NULL;
    int mapped = 0;
    if (size > (size_t)-1 - 8192)
        return NULL;
#if !defined(_MSC_VER)
    if (size >= POOL_MIN) {
        size_t len = (size + HEAD + 4095) & ~(size_t)4095;
        void *m = mmap(NULL, len, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
        if (m == MAP_FAILED)
            return NULL;
#if defined(MADV_HUGEPAGE)
        madvise(m, len, MADV_HUGEPAGE);
#endif
        h = m, mapped = 1, size = len - HEAD;
    } else if (posix_memalign((void **)&h, 64, size + HEAD))
        return NULL;
#else
    if (!(h = malloc(size + HEAD))) /* malloc's alignment: nothing is streamed without gcc */
        return NULL;
#endif
    h->size = size, h->mapped = mapped;
    return (char *)h + HEAD;
}

static void *pool_malloc(void *ctx, size_t size)
{
    (void)ctx;
    if (size >= POOL_MIN) {
        char *at = NULL;
        pool_enter();
        int best = -1;
        for (int i = 0; i < nkept; i++) /* the smallest that holds it; of equals, the one kept last */
            if (kept[i].size >= size && kept[i].size / 2 <= size &&
                (best < 0 || kept[i].size < kept[best].size ||
                 (kept[i].size == kept[best].size && kept[i].since >= kept[best].since)))
                best = i;
        if (best >= 0) {
            at = kept[best].at, kept_bytes -= kept[best].size;
            kept[best] = kept[--nkept];
            pool_reused++;
        } else
            pool_fresh++;
        pool_leave();
        if (at)
            return at;
    }
    return new_block(size);
}
static void *pool_calloc(void *ctx, size_t n, size_t size)
{
    if (size && n > (size_t)-1 / size)
        return NULL;
    void *at = pool_malloc(ctx, n * size);
    if (at)
        memset(at, 0, n * size);
    return at;
}
static void pool_free(void *ctx, void *at, size_t size)
{
    (void)ctx, (void)size; /* the header has the block's own size */
    if (!at)
        return;
    Head *h = head_of(at);
    int start = 0;
    if (h->mapped) {
        pool_enter();
        if (nkept < POOL_SLOTS && kept_bytes + h->size <= POOL_MAX) {
            kept[nkept].at = at, kept[nkept].size = h->size, kept[nkept].since = seconds();
            kept[nkept].call = calls;
            nkept++, kept_bytes += h->size, at = NULL;
            start = !reaping, reaping = 1;
        }
        pool_leave();
    }
    if (at)
        let_go(at);
    if (start && start_reaper() < 0) { /* no thread: nothing kept */
        pool_enter();
        reaping = 0; /* first: a block kept meanwhile starts a thread of its own */
        pool_leave();
        give_back(0.0, 1);
    }
}
/* a block that holds `size` already stays; else the bytes move to a new one */
static void *pool_realloc(void *ctx, void *at, size_t size)
{
    if (!at)
        return pool_malloc(ctx, size);
    size_t had = head_of(at)->size;
    if (size <= had)
        return at;
    void *to = pool_malloc(ctx, size);
    if (to) {
        memcpy(to, at, had);
        pool_free(ctx, at, had);
    }
    return to;
}
static PyDataMem_Handler pool_handler = {
    "hconv", 1, {NULL, pool_malloc, pool_calloc, pool_realloc, pool_free}};
static PyObject *pool_capsule; /* the handler as numpy takes it, made once */

/* outputs(n, diagnostics): new arrays for a call of n rows from the pool's memory: w (n, 3) and
 * cond float64, code uint8, residual float64 (n,) with diagnostics or (0,), fallback bool. */
static PyObject *outputs(PyObject *self, PyObject *args)
{
    Py_ssize_t n;
    int diagnostics;
    if (!PyArg_ParseTuple(args, "np", &n, &diagnostics))
        return NULL;
    if (n < 0) {
        PyErr_SetString(PyExc_ValueError, "rowcode.outputs: n must not be negative");
        return NULL;
    }
    if (!pool_capsule && !(pool_capsule = PyCapsule_New(&pool_handler, "mem_handler", NULL)))
        return NULL;
    pool_enter();
    calls++;
    pool_leave();
    give_back(seconds() - POOL_IDLE, 0);
    PyObject *before = PyDataMem_SetHandler(pool_capsule);
    if (!before)
        return NULL;
    npy_intp shapes[5][2] = {{n, 3}, {n, 0}, {n, 0}, {diagnostics ? n : 0, 0}, {n, 0}};
    int types[5] = {NPY_FLOAT64, NPY_FLOAT64, NPY_UINT8, NPY_FLOAT64, NPY_BOOL};
    PyObject *out = PyTuple_New(5);
    for (int i = 0; out && i < 5; i++) { /* the first that fails says why, with its own shape */
        PyObject *a = PyArray_SimpleNew(i == 0 ? 2 : 1, shapes[i], types[i]);
        if (!a)
            Py_CLEAR(out);
        else
            PyTuple_SET_ITEM(out, i, a);
    }
    PyObject *after = PyDataMem_SetHandler(before);
    Py_DECREF(before);
    if (!after) {
        Py_XDECREF(out);
        return NULL;
    }
    Py_DECREF(after);
    return out;
}

/* pool(): what the pool keeps now (blocks, bytes), the requests it has served from kept blocks
 * and with fresh memory since the process began, and its limits; release(): gives back every
 * block kept. */
static PyObject *pool(PyObject *self, PyObject *args)
{
    pool_enter();
    int blocks = nkept;
    size_t bytes = kept_bytes;
    long long reused = pool_reused, fresh = pool_fresh;
    pool_leave();
    return Py_BuildValue("{s:i,s:n,s:L,s:L,s:n,s:n,s:i,s:d}", "blocks", blocks, "bytes", (Py_ssize_t)bytes, "reused",
                         reused, "fresh", fresh, "least_bytes", (Py_ssize_t)POOL_MIN, "most_bytes",
                         (Py_ssize_t)POOL_MAX, "most_blocks", POOL_SLOTS, "idle_seconds", POOL_IDLE);
}
static PyObject *release(PyObject *self, PyObject *args)
{
    give_back(0.0, 1);
    Py_RETURN_NONE;
}

/* rows lo..hi of jb; returns how many fell back. The fence after streamed chunks orders their
 * stores before the count of rows done that tells the caller they are written, and before the
 * fallback flags read here. */
static npy_intp rows(const Job *jb, Chunk *s, npy_intp lo, npy_intp hi)
{
    for (npy_intp i = lo; i < hi; i += CH)
        convert_chunk(jb, s, i, (int)(hi - i < CH ? hi - i : CH));
    if (jb->stream)
        store_fence();
    npy_intp lost = 0;
    for (npy_intp i = lo; i < hi; i++)
        lost += jb->fallback[i] != 0;
    return lost;
}

/* Takes and converts one block of the post, if one is left: the rows it converted, 0 when it
 * lost a race for the block (look again at once), -1 when the post has none left to take
 * (`seen`: the word it found so). */
static npy_intp take_block(Chunk *s, uint64_t *seen)
{
    uint64_t w = *seen = load_word();
    uint32_t block = (uint32_t)w;
    if (block == BUSY)
        return -1;
    Post p = post;
    fence();
    if (block >= p.blocks)
        return -1;
    if (!swap_word(w, w + 1))
        return 0;
    npy_intp lo = (npy_intp)block * p.size, hi = p.n - lo < p.size ? p.n : lo + p.size;
    add(&rows_lost, (npy_int64)rows(&p.jb, s, lo, hi));
    add(&rows_done, (npy_int64)(hi - lo));
    return hi - lo;
}

/* serve(linger): this thread takes the blocks of the calls the process's callers share (share),
 * without the GIL, until no call has been posted for `linger` seconds; returns how many blocks it
 * took; `linger` counts from its last block or the last call it saw posted, whichever is later.
 * Between calls it reads only the word, until the word changes; it spins SPINS looks after each
 * call, then gives its core away between looks, so that on a busy machine a thread waiting for a
 * call does not hold a core that other work wants. */
static PyObject *serve(PyObject *self, PyObject *args)
{
    double linger;
    if (!PyArg_ParseTuple(args, "d", &linger))
        return NULL;
    if (!(linger >= 0.0 && linger <= 3600.0)) { /* NaN too: a thread that never returns */
        PyErr_SetString(PyExc_ValueError, "rowcode.serve: linger in seconds, 0 to 3600");
        return NULL;
    }
    Chunk *s = PyMem_RawMalloc(sizeof(Chunk));
    if (!s)
        return PyErr_NoMemory();
    long taken = 0;
    Py_BEGIN_ALLOW_THREADS;
    add_int(&serving, 1);
    double last = seconds();
    /* idle: the word last found with no block to take (look again when it changes); at first
     * none, so that a thread started during a call takes that call's blocks */
    uint64_t idle = UINT64_MAX, generation = UINT64_MAX;
    for (unsigned long looks = 0;; looks++) {
        if (load_word() != idle) {
            npy_intp got = take_block(s, &idle);
            if (got >= 0) {
                taken += got > 0;
                last = seconds(), looks = 0;
                continue;
            }
        }
        if (idle >> 32 != generation) /* a call was posted since the last look */
            generation = idle >> 32, last = seconds(), looks = 0;
        if (looks < SPINS)
            relax();
        else
            yield_core();
        if (looks % 256 == 255 && seconds() - last > linger)
            break;
    }
    add_int(&serving, -1);
    Py_END_ALLOW_THREADS;
    PyMem_RawFree(s);
    return PyLong_FromLong(taken);
}

/* serving(): how many threads are in serve() now. */
static PyObject *serving_now(PyObject *self, PyObject *args) { return PyLong_FromLong(read_int(&serving)); }

/* the arguments convert and share begin with, then one integer (b NULL) or two */
static int parse_rows(PyObject *args, Job *jb, npy_intp *n, Py_ssize_t *a, Py_ssize_t *b)
{
    const char *format = b ? "O!pO!ppdO!O!O!O!O!pnn" : "O!pO!ppdO!O!O!O!O!pn";
    PyArrayObject *In, *H, *w, *cond, *code, *residual, *fallback;
    int nine, refined, diagnostics, stream;
    double cond_limit;
    if (!PyArg_ParseTuple(args, format, &PyArray_Type, &In, &nine, &PyArray_Type, &H, &refined, &diagnostics,
                          &cond_limit, &PyArray_Type, &w, &PyArray_Type, &cond, &PyArray_Type, &code, &PyArray_Type,
                          &residual, &PyArray_Type, &fallback, &stream, a, b))
        return -1;
    if (!K.ready) {
        PyErr_SetString(PyExc_RuntimeError, "rowcode: configure() first");
        return -1;
    }
    if (PyArray_NDIM(H) != 2) {
        PyErr_SetString(PyExc_ValueError, "rowcode: H must be (3, N)");
        return -1;
    }
    *n = PyArray_DIM(H, 1);
    if (check(H, "H", 2, 3, *n, NPY_FLOAT64, 0) || check(In, "I", 2, nine ? 9 : 6, *n, NPY_FLOAT64, 0) ||
        check(w, "w", 2, *n, 3, NPY_FLOAT64, 1) || check(cond, "cond", 1, *n, 0, NPY_FLOAT64, 1) ||
        check(code, "code", 1, *n, 0, NPY_UINT8, 1) || check(fallback, "fallback", 1, *n, 0, NPY_BOOL, 1) ||
        check(residual, "residual", 1, diagnostics ? *n : PyArray_DIM(residual, 0), 0, NPY_FLOAT64, 1))
        return -1;
    Job j = {PyArray_BYTES(In), PyArray_BYTES(H), PyArray_STRIDE(In, 0), PyArray_STRIDE(In, 1),
             PyArray_STRIDE(H, 0), PyArray_STRIDE(H, 1), nine, refined, diagnostics, cond_limit,
             (double *)PyArray_DATA(w), (double *)PyArray_DATA(cond), (double *)PyArray_DATA(residual),
             (uint8_t *)PyArray_DATA(code), (npy_bool *)PyArray_DATA(fallback), stream};
    *jb = j;
    return 0;
}

/* convert(I, nine, H, refined, diagnostics, cond_limit, w, cond, code, residual, fallback, stream,
 * start, stop): rows start..stop of I and H into the same rows of the outputs (residual written
 * with diagnostics only), a chunk of CH rows at a time, on this thread without the GIL, whole
 * chunks streamed to outputs aligned for it with `stream` (chunk_body); returns how many of them
 * are fallback. */
static PyObject *convert(PyObject *self, PyObject *args)
{
    Job jb;
    npy_intp n;
    Py_ssize_t start, stop;
    if (parse_rows(args, &jb, &n, &start, &stop) < 0)
        return NULL;
    if (start < 0 || stop > n || start > stop) {
        PyErr_SetString(PyExc_ValueError, "rowcode.convert: rows start..stop out of range");
        return NULL;
    }
    Chunk *s = PyMem_RawMalloc(sizeof(Chunk));
    if (!s)
        return PyErr_NoMemory();
    npy_intp lost;
    Py_BEGIN_ALLOW_THREADS;
    lost = rows(&jb, s, start, stop);
    Py_END_ALLOW_THREADS;
    PyMem_RawFree(s);
    return PyLong_FromSsize_t(lost);
}

/* share(I, nine, H, refined, diagnostics, cond_limit, w, cond, code, residual, fallback, stream, size):
 * every row, as convert's, in blocks of `size` rows posted to the threads serving, the caller
 * taking blocks too; returns once every row is done, by whichever thread: (rows that fell back,
 * rows this thread converted). While another caller's rows are posted, the caller converts
 * every row itself. */
static PyObject *share(PyObject *self, PyObject *args)
{
    Job jb;
    npy_intp n;
    Py_ssize_t size;
    if (parse_rows(args, &jb, &n, &size, NULL) < 0)
        return NULL;
    /* without n + size - 1, which overflows for a huge size; compared unsigned, as BUSY is -1 in
     * a 32-bit npy_intp */
    npy_intp blocks = size < 1 ? 0 : n / size + (n % size != 0);
    if (size < 1 || (uint64_t)blocks >= (uint64_t)BUSY) {
        PyErr_SetString(PyExc_ValueError, "rowcode.share: a block size of at least one row, fewer than 2**32 blocks");
        return NULL;
    }
    Chunk *s = PyMem_RawMalloc(sizeof(Chunk));
    if (!s)
        return PyErr_NoMemory();
    npy_intp lost, own = n;
    Py_BEGIN_ALLOW_THREADS;
    if (!take_slot(&owned))
        lost = rows(&jb, s, 0, n);
    else {
        uint64_t generation = (load_word() >> 32) + 1;
        store_word(generation << 32 | BUSY);
        fence();
        post.jb = jb, post.n = n, post.size = size, post.blocks = (uint32_t)blocks;
        set_count(&rows_done, 0), set_count(&rows_lost, 0);
        store_word(generation << 32);
        own = 0;
        uint64_t seen;
        for (npy_intp got; (got = take_block(s, &seen)) >= 0;)
            own += got;
        for (npy_int64 spins = 0; read_count(&rows_done) < (npy_int64)n; spins++)
            if (spins < SPINS)
                relax();
            else
                yield_core();
        lost = (npy_intp)read_count(&rows_lost);
        give_slot(&owned);
    }
    Py_END_ALLOW_THREADS;
    PyMem_RawFree(s);
    return Py_BuildValue("(nn)", lost, own);
}

/* one(I, nine, H, refined, diagnostics, cond_limit): one body, I (3, 3) or (6,) and H (3,)
 * contiguous float64 (else None: the caller takes the general path), converted with the GIL held
 * (a few microseconds): (w (3,), cond, code, residual, fallback), numpy scalars as a stacked
 * result's rows are, residual None without diagnostics. */
static PyObject *one(PyObject *self, PyObject *args)
{
    PyArrayObject *In, *H;
    int nine, refined, diagnostics;
    double cond_limit;
    if (!PyArg_ParseTuple(args, "O!pO!ppd", &PyArray_Type, &In, &nine, &PyArray_Type, &H, &refined, &diagnostics,
                          &cond_limit))
        return NULL;
    if (!K.ready || PyArray_TYPE(In) != NPY_FLOAT64 || PyArray_TYPE(H) != NPY_FLOAT64 ||
        !PyArray_IS_C_CONTIGUOUS(In) || !PyArray_IS_C_CONTIGUOUS(H) || PyArray_SIZE(H) != 3 ||
        PyArray_SIZE(In) != (nine ? 9 : 6))
        Py_RETURN_NONE;
    double w[3], cond, residual = NAN;
    uint8_t code;
    npy_bool fallback;
    Job jb = {PyArray_BYTES(In), PyArray_BYTES(H), sizeof(double), 0, sizeof(double), 0, nine, refined, diagnostics,
              cond_limit, w, &cond, &residual, &code, &fallback, 0};
    Chunk s; /* about 26 kB of stack */
    convert_chunk(&jb, &s, 0, 1);
    npy_intp three = 3;
    PyObject *wa = PyArray_SimpleNew(1, &three, NPY_FLOAT64);
    if (!wa)
        return NULL;
    memcpy(PyArray_DATA((PyArrayObject *)wa), w, sizeof w);
    PyArray_Descr *f64 = PyArray_DescrFromType(NPY_FLOAT64), *u8 = PyArray_DescrFromType(NPY_UINT8);
    PyObject *c = PyArray_Scalar(&cond, f64, NULL), *k = PyArray_Scalar(&code, u8, NULL);
    PyObject *r = diagnostics ? PyArray_Scalar(&residual, f64, NULL) : (Py_INCREF(Py_None), Py_None);
    Py_DECREF(f64);
    Py_DECREF(u8);
    if (!c || !k || !r) {
        Py_XDECREF(c), Py_XDECREF(k), Py_XDECREF(r), Py_DECREF(wa);
        return NULL;
    }
    return Py_BuildValue("(NNNNO)", wa, c, k, r, fallback ? Py_True : Py_False);
}

/* stack(I, H, refined, diagnostics, cond_limit): a stack of bodies as numpy users hold it, I
 * (N, 3, 3) (its rows of three contiguous) or (N, 6) and H (N, 3), float64, converted on the
 * caller's thread into new arrays: (w (N, 3), cond, code, residual or None). None when a row is
 * left to the numpy engine, or for arrays of another layout: the caller then takes the general
 * path. For small stacks, whose cost is mostly the call's. */
static PyObject *stack(PyObject *self, PyObject *args)
{
    PyArrayObject *In, *H;
    int refined, diagnostics;
    double cond_limit;
    if (!PyArg_ParseTuple(args, "O!O!ppd", &PyArray_Type, &In, &PyArray_Type, &H, &refined, &diagnostics,
                          &cond_limit))
        return NULL;
    if (!K.ready || PyArray_TYPE(In) != NPY_FLOAT64 || PyArray_TYPE(H) != NPY_FLOAT64 || PyArray_NDIM(H) != 2 ||
        PyArray_DIM(H, 1) != 3)
        Py_RETURN_NONE;
    npy_intp n = PyArray_DIM(H, 0);
    int nine = PyArray_NDIM(In) == 3;
    if (PyArray_DIM(In, 0) != n || n == 0)
        Py_RETURN_NONE;
    if (nine ? PyArray_DIM(In, 1) != 3 || PyArray_DIM(In, 2) != 3 || PyArray_STRIDE(In, 1) != 3 * PyArray_STRIDE(In, 2)
             : PyArray_NDIM(In) != 2 || PyArray_DIM(In, 1) != 6)
        Py_RETURN_NONE;
    npy_intp dims[2] = {n, 3};
    PyObject *w = PyArray_SimpleNew(2, dims, NPY_FLOAT64), *cond = PyArray_SimpleNew(1, dims, NPY_FLOAT64);
    PyObject *code = PyArray_SimpleNew(1, dims, NPY_UINT8);
    PyObject *res = diagnostics ? PyArray_SimpleNew(1, dims, NPY_FLOAT64) : (Py_INCREF(Py_None), Py_None);
    npy_bool *fallback = PyMem_RawMalloc(n * sizeof(npy_bool));
    Chunk *s = PyMem_RawMalloc(sizeof(Chunk));
    if (!w || !cond || !code || !res || !fallback || !s) {
        Py_XDECREF(w), Py_XDECREF(cond), Py_XDECREF(code), Py_XDECREF(res);
        PyMem_RawFree(fallback), PyMem_RawFree(s);
        return PyErr_NoMemory();
    }
    Job jb = {PyArray_BYTES(In), PyArray_BYTES(H), PyArray_STRIDE(In, PyArray_NDIM(In) - 1), PyArray_STRIDE(In, 0),
              PyArray_STRIDE(H, 1), PyArray_STRIDE(H, 0), nine, refined, diagnostics, cond_limit,
              (double *)PyArray_DATA((PyArrayObject *)w), (double *)PyArray_DATA((PyArrayObject *)cond),
              diagnostics ? (double *)PyArray_DATA((PyArrayObject *)res) : NULL,
              (uint8_t *)PyArray_DATA((PyArrayObject *)code), fallback, 0};
    npy_intp lost = 0;
    Py_BEGIN_ALLOW_THREADS;
    for (npy_intp i = 0; i < n; i += CH)
        convert_chunk(&jb, s, i, (int)(n - i < CH ? n - i : CH));
    for (npy_intp i = 0; i < n; i++)
        lost += fallback[i] != 0;
    Py_END_ALLOW_THREADS;
    PyMem_RawFree(fallback), PyMem_RawFree(s);
    if (lost) {
        Py_DECREF(w), Py_DECREF(cond), Py_DECREF(code), Py_DECREF(res);
        Py_RETURN_NONE;
    }
    return Py_BuildValue("(NNNN)", w, cond, code, res);
}

/* kernels(): the names of the versions of the chunk code this CPU runs, the one in use first.
 * use(name): convert with that version from now on (tests compare their bits); returns None. */
static PyObject *kernels(PyObject *self, PyObject *args)
{
    const char *names[3];
    ChunkFn fns[3];
    int k = kernels_of_cpu(names, fns);
    PyObject *out = PyList_New(0);
    for (int i = 0; out && i < k; i++) {
        PyObject *name = PyUnicode_FromString(names[i]);
        if (!name || (fns[i] == convert_chunk ? PyList_Insert(out, 0, name) : PyList_Append(out, name)) < 0)
            Py_CLEAR(out);
        Py_XDECREF(name);
    }
    return out;
}

static PyObject *use(PyObject *self, PyObject *args)
{
    const char *want, *names[3];
    ChunkFn fns[3];
    if (!PyArg_ParseTuple(args, "s", &want))
        return NULL;
    int k = kernels_of_cpu(names, fns);
    for (int i = 0; i < k; i++)
        if (strcmp(names[i], want) == 0) {
            convert_chunk = fns[i];
            Py_RETURN_NONE;
        }
    PyErr_Format(PyExc_ValueError, "rowcode.use: this CPU has no version %s", want);
    return NULL;
}

static PyMethodDef methods[] = {
    {"kernels", kernels, METH_NOARGS, "kernels(): the versions of the chunk code this CPU runs, the one in use first."},
    {"use", use, METH_VARARGS, "use(name): convert with that version of the chunk code (for tests)."},
    {"stack", stack, METH_VARARGS, "stack(I, H, refined, diagnostics, cond_limit): a small stack, or None."},
    {"one", one, METH_VARARGS, "one(I, nine, H, refined, diagnostics, cond_limit): one body, or None."},
    {"configure", configure, METH_VARARGS, "configure(constants): the constants of hconv's Python modules."},
    {"convert", convert, METH_VARARGS,
     "convert(I, nine, H, refined, diagnostics, cond_limit, w, cond, code, residual, fallback, stream, start, stop)"},
    {"share", share, METH_VARARGS,
     "share(I, nine, H, refined, diagnostics, cond_limit, w, cond, code, residual, fallback, stream, size)"},
    {"serve", serve, METH_VARARGS, "serve(linger): take the blocks of shared calls until none comes for linger s."},
    {"serving", serving_now, METH_NOARGS, "serving(): how many threads are in serve() now."},
    {"outputs", outputs, METH_VARARGS, "outputs(n, diagnostics): a call's output arrays, from the pool's memory."},
    {"pool", pool, METH_NOARGS, "pool(): what the pool of outputs() keeps, has served, and its limits."},
    {"release", release, METH_NOARGS, "release(): give back every block the pool keeps."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "rowcode", "hconv's compiled row code.", -1, methods};

PyMODINIT_FUNC PyInit_rowcode(void)
{
    import_array();
    const char *names[3];
    ChunkFn fns[3];
    kernels_of_cpu(names, fns);
    convert_chunk = fns[0];
    on_fork();
    PyObject *m = PyModule_Create(&module);
    if (m && PyModule_AddIntConstant(m, "CHUNK_ROWS", CH) < 0)
        Py_CLEAR(m);
    return m;
}
