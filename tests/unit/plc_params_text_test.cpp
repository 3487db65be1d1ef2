// How tgm-plc logs an M-function's parameters (client/plc/params_text.hpp).
#include "params_text.hpp"

#include <gtest/gtest.h>

#include <array>
#include <string>

namespace tgm::plc {
namespace {

// The values the PLC got, exactly: `M1001 A-0.000001 B123456789.123` was logged as
// "A-1e-06 B1.23457e+08" (printf's %g), not the value in M_Function_Parameter (review of
// session 76, F7).
TEST(PlcParamsText, EachParameterIsShownWithEveryDigit) {
  MParams p = unset_params();
  EXPECT_EQ(params_text(p), "none");
  p[0] = -0.000001;
  p[1] = 123456789.123;
  EXPECT_EQ(params_text(p), "A-1e-06 B123456789.123");
  p = unset_params();
  p[18] = 12000;      // S: a spindle speed
  p[23] = 0.1 + 0.2;  // X: not 0.3 as a double
  p[25] = -26.5;      // Z
  EXPECT_EQ(params_text(p), "S12000 X0.30000000000000004 Z-26.5");
  p = unset_params();
  p[19] = 2;  // T2 (M6 T2)
  EXPECT_EQ(params_text(p), "T2");
}

}  // namespace
}  // namespace tgm::plc
