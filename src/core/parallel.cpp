#include "core/parallel.h"

#include <omp.h>

namespace hivox {

namespace {
int g_default_threads = 0;
}

int thread_count() {
  return omp_get_max_threads();
}

void set_thread_count(int n) {
  if (g_default_threads == 0) g_default_threads = omp_get_max_threads();
  omp_set_num_threads(n > 0 ? n : g_default_threads);
}

namespace detail {
int thread_index() {
  return omp_get_thread_num();
}
int team_size() {
  return omp_get_num_threads();
}
void use_thread_count(int n) {
  omp_set_num_threads(n > 0 ? n : 1);
}
}  // namespace detail

void ThreadTeam::barrier() const {
#pragma omp barrier
}

}  // namespace hivox
