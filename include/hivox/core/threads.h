#pragma once
/// @file
/// How many CPU threads hivox's parallel loops use.

namespace hivox {

/// Threads used by hivox loops (by default the machine's, usually the core count).
int thread_count();
/// Sets the thread count for hivox loops; `n <= 0` restores the default.
void set_thread_count(int n);

}  // namespace hivox
