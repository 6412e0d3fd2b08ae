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
  // Rounding x log2(e) to a float costs up to half an ulp of it, i.e. 2.7e-6 relative near -87.
  EXPECT_LT(worst, 3e-6) << "largest relative error";
  EXPECT_EQ(exp_nonpositive(0.0f), 1.0f);
  EXPECT_EQ(exp_nonpositive(-1000.0f), 0.0f);
  EXPECT_EQ(exp_nonpositive(-1e9f), 0.0f);
}

}  // namespace
}  // namespace hivox
