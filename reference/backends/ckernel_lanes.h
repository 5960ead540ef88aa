/* Helpers of the generated C kernels (reference/ckernels.py), included before their bodies:
   the NaN-propagating minimum of the pivot ratios, and the four-lane vector type of the
   batched forward body with its per-lane functions. Every helper computes each lane exactly
   as the scalar code computes one state (the same libm calls, the same operations). */
#ifndef CKERNEL_LANES_H
#define CKERNEL_LANES_H

static inline double nmin(double a, double b)
{
    if (a != a || b != b) return a + b; /* NaN: Python's min() would drop it */
    return a < b ? a : b;
}

#define LANES 4
typedef double vd __attribute__((vector_size(LANES * sizeof(double))));
#define INLINE static inline __attribute__((always_inline))

INLINE vd splat(double x) { return (vd){x, x, x, x}; }
INLINE vd v_sq(vd x) { return x * x; }

#define LANEWISE1(name, f)                                                                    \
    INLINE vd name(vd x)                                                                      \
    {                                                                                         \
        vd r;                                                                                 \
        for (int j = 0; j < LANES; ++j) r[j] = f(x[j]);                                       \
        return r;                                                                             \
    }
#define LANEWISE2(name, f)                                                                    \
    INLINE vd name(vd x, vd y)                                                                \
    {                                                                                         \
        vd r;                                                                                 \
        for (int j = 0; j < LANES; ++j) r[j] = f(x[j], y[j]);                                 \
        return r;                                                                             \
    }
LANEWISE1(v_sin, sin)
LANEWISE1(v_cos, cos)
LANEWISE1(v_tan, tan)
LANEWISE1(v_sqrt, sqrt)
LANEWISE1(v_exp, exp)
LANEWISE1(v_log, log)
LANEWISE1(v_asin, asin)
LANEWISE1(v_acos, acos)
LANEWISE1(v_atan, atan)
LANEWISE2(v_atan2, atan2)
LANEWISE2(v_pow, pow)

/* nmin on every lane without a branch: a + b where either is NaN, else a < b ? a : b, as the
   scalar nmin (the same comparison and the same sum per lane, selected by masks). The lanewise
   loop compiled to a compare and a branch per lane through memory. */
typedef long long vmask __attribute__((vector_size(LANES * sizeof(double))));
INLINE vd v_nmin(vd a, vd b)
{
    const vmask nan = (a != a) | (b != b), lt = a < b;
    const vmask least = (lt & (vmask)a) | (~lt & (vmask)b);
    return (vd)((nan & (vmask)(a + b)) | (~nan & least));
}

INLINE void v_sincos(vd x, vd *s, vd *c)
{
    for (int j = 0; j < LANES; ++j) {
        double sj, cj;
        __builtin_sincos(x[j], &sj, &cj);
        (*s)[j] = sj;
        (*c)[j] = cj;
    }
}

#endif
