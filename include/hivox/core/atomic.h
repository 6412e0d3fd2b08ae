#pragma once
/// @file
/// The one atomic wrapper used by kernels: `std::atomic_ref` on the CPU, CUDA intrinsics on the
/// device. All functions return the value held before the operation.

#include <cstdint>

#include "hivox/core/hd.h"

#if !defined(__CUDA_ARCH__)
#include <atomic>
#endif

namespace hivox {

HIVOX_HD inline int32_t atomic_cas(int32_t* address, int32_t expected, int32_t desired) {
#if defined(__CUDA_ARCH__)
  return atomicCAS(address, expected, desired);
#else
  std::atomic_ref<int32_t>(*address).compare_exchange_strong(expected, desired,
                                                             std::memory_order_acq_rel);
  return expected;  // on failure compare_exchange wrote the current value here
#endif
}

HIVOX_HD inline int32_t atomic_add(int32_t* address, int32_t value) {
#if defined(__CUDA_ARCH__)
  return atomicAdd(address, value);
#else
  return std::atomic_ref<int32_t>(*address).fetch_add(value, std::memory_order_acq_rel);
#endif
}

HIVOX_HD inline int32_t atomic_exchange(int32_t* address, int32_t value) {
#if defined(__CUDA_ARCH__)
  return atomicExch(address, value);
#else
  return std::atomic_ref<int32_t>(*address).exchange(value, std::memory_order_acq_rel);
#endif
}

HIVOX_HD inline int32_t atomic_load(int32_t* address) {
#if defined(__CUDA_ARCH__)
  return *static_cast<volatile int32_t*>(address);
#else
  return std::atomic_ref<int32_t>(*address).load(std::memory_order_acquire);
#endif
}

HIVOX_HD inline void atomic_store(int32_t* address, int32_t value) {
#if defined(__CUDA_ARCH__)
  atomicExch(address, value);
#else
  std::atomic_ref<int32_t>(*address).store(value, std::memory_order_release);
#endif
}

HIVOX_HD inline int32_t atomic_max(int32_t* address, int32_t value) {
#if defined(__CUDA_ARCH__)
  return atomicMax(address, value);
#else
  int32_t current = std::atomic_ref<int32_t>(*address).load(std::memory_order_relaxed);
  while (value > current && !std::atomic_ref<int32_t>(*address).compare_exchange_weak(
                                current, value, std::memory_order_acq_rel)) {
  }
  return current;
#endif
}

HIVOX_HD inline int32_t atomic_min(int32_t* address, int32_t value) {
#if defined(__CUDA_ARCH__)
  return atomicMin(address, value);
#else
  int32_t current = std::atomic_ref<int32_t>(*address).load(std::memory_order_relaxed);
  while (value < current && !std::atomic_ref<int32_t>(*address).compare_exchange_weak(
                                current, value, std::memory_order_acq_rel)) {
  }
  return current;
#endif
}

/// Atomic minimum / maximum of non-negative floats (their bit patterns order like integers).
HIVOX_HD inline void atomic_min_positive(float* address, float value) {
  int32_t* bits = reinterpret_cast<int32_t*>(address);
  int32_t desired;
  __builtin_memcpy(&desired, &value, sizeof desired);
  int32_t current = atomic_load(bits);
  while (desired < current) {
    const int32_t seen = atomic_cas(bits, current, desired);
    if (seen == current) break;
    current = seen;
  }
}
HIVOX_HD inline void atomic_max_positive(float* address, float value) {
  int32_t* bits = reinterpret_cast<int32_t*>(address);
  int32_t desired;
  __builtin_memcpy(&desired, &value, sizeof desired);
  int32_t current = atomic_load(bits);
  while (desired > current) {
    const int32_t seen = atomic_cas(bits, current, desired);
    if (seen == current) break;
    current = seen;
  }
}

}  // namespace hivox
