#pragma once
/// @file
/// Host/device qualifiers. Math shared by the CPU and the CUDA drivers is written once
/// as `HIVOX_HD inline` functions on plain types; this header is the only place that knows
/// whether a CUDA compiler is looking.

#define HIVOX_PRAGMA(x) _Pragma(#x)

/// Defined in CUDA code: compiled by nvcc, or by the host compiler against the CPU emulation of
/// CUDA (-DHIVOX_CUDA_EMULATION=ON, src/cuda/emulation). Kernels and launches are written there.
#if defined(__CUDACC__) || defined(HIVOX_CUDA_EMULATION)
#define HIVOX_CUDA_CODE 1
#endif

#if defined(__CUDACC__)
#define HIVOX_HD __host__ __device__
#define HIVOX_UNROLL(n) HIVOX_PRAGMA(unroll n)
#define HIVOX_NOINLINE __noinline__
#define HIVOX_FORCEINLINE __forceinline__
/// Keeps a large function that many call sites share out of line in GPU code: a kernel with
/// every sampling function inlined at each call runs to hundreds of KB of code, and its warps
/// then stall on instruction fetches.
#if defined(__CUDA_ARCH__)
#define HIVOX_DEVICE_NOINLINE __noinline__
#else
#define HIVOX_DEVICE_NOINLINE
#endif
#else
#define HIVOX_HD
/// Keeps a rarely taken path out of line so that the common path around it can be inlined.
#define HIVOX_NOINLINE __attribute__((noinline))
/// Inlines a function everywhere: a loop calling it can then be vectorized.
#define HIVOX_FORCEINLINE inline __attribute__((always_inline))
/// Keeps a function out of line in GPU code only (see the CUDA branch above): inlined here.
#define HIVOX_DEVICE_NOINLINE
/// Unrolls the loop that follows `n` times (a vectorizer cannot take a loop nest with inner
/// loops).
#if defined(__clang__)
#define HIVOX_UNROLL(n) HIVOX_PRAGMA(unroll n)
#else
#define HIVOX_UNROLL(n) HIVOX_PRAGMA(GCC unroll n)
#endif
#endif
