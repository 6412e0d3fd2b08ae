#include "hivox/core/math.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

namespace hivox {
namespace {

TEST(Math, ExpNonpositiveMatchesStdExp) {
  // Dense over the range where e^x is a normal float.
  double worst = 0.0;
  for (int i = 0; i <= 800000; ++i) {
    const float x = -87.0f * static_cast<float>(i) / 800000.0f;
    const double exact = std::exp(static_cast<double>(x));
    worst = std::max(worst, std::abs(exp_nonpositive(x) - exact) / exact);
  }
  // Near -87, x log2(e) ~ -125.5: rounding it to a float costs half an ulp (2^-18), i.e. 2.6e-6
  // relative after the power of two, and log2(e) as a float (relative error 1.3e-8) another
  // 1.1e-6; the degree-6 polynomial adds a few float ulps. How much of this shows depends on
  // which products the compiler fuses (3.0e-6 at -O3, 3.9e-6 at -O1 with -march=native).
  EXPECT_LT(worst, 4.2e-6) << "largest relative error";
  EXPECT_EQ(exp_nonpositive(0.0f), 1.0f);
  EXPECT_EQ(exp_nonpositive(-1000.0f), 0.0f);
  EXPECT_EQ(exp_nonpositive(-1e9f), 0.0f);
}

}  // namespace
}  // namespace hivox
