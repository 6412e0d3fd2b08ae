#pragma once
/// @file
/// CPU parallel loops (OpenMP). Kernel bodies are written once as functions of an index; this is
/// the CPU launcher (a CUDA driver launches the same body as a grid-stride loop).

#include <cstdint>

#include <omp.h>

namespace hivox {

/// Threads used by hivox loops (defaults to OpenMP's choice, usually the core count).
int thread_count();
/// Sets the thread count for hivox loops; `n <= 0` restores the default.
void set_thread_count(int n);

/// Runs `body(i)` for i in [0, n) on all threads, static schedule (equal-cost items).
template <typename Body>
void parallel_for(int64_t n, Body&& body) {
#pragma omp parallel for schedule(static)
  for (int64_t i = 0; i < n; ++i) body(i);
}

/// Runs `body(i)` for i in [0, n) with dynamic scheduling in chunks (uneven-cost items).
template <typename Body>
void parallel_for_dynamic(int64_t n, int64_t chunk, Body&& body) {
#pragma omp parallel for schedule(dynamic, chunk)
  for (int64_t i = 0; i < n; ++i) body(i);
}

/// Runs `body(thread_index, thread_count)` once on each thread.
template <typename Body>
void parallel_threads(Body&& body) {
#pragma omp parallel
  body(omp_get_thread_num(), omp_get_num_threads());
}

}  // namespace hivox
