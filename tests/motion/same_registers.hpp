// Comparing the registers of two interpolators that must agree (advance() and step(), an
// incremental LookAheadBuffer and its rebuild): every register by name, so a failure says which.
#pragma once

#include <gtest/gtest.h>

#include <cstddef>
#include <string>

#include "tgm/registers.hpp"

namespace tgm::test {

// Every register, compared exactly (doubles with ==, so -0.0 == 0.0 is the only slack).
inline void expect_same_registers(const Registers& a, const Registers& b, const std::string& ctx) {
  ASSERT_EQ(a.cycle, b.cycle) << ctx;
  EXPECT_EQ(a.status, b.status) << ctx;
  EXPECT_EQ(a.run_flag, b.run_flag) << ctx;
  EXPECT_EQ(a.act_part, b.act_part) << ctx;
  EXPECT_EQ(a.act_line, b.act_line) << ctx;
  EXPECT_EQ(a.m_func, b.m_func) << ctx;
  EXPECT_EQ(a.act_g_func, b.act_g_func) << ctx;
  EXPECT_EQ(a.act_m_func, b.act_m_func) << ctx;
  EXPECT_EQ(a.last_cont_m_func, b.last_cont_m_func) << ctx;
  EXPECT_EQ(a.tool_number, b.tool_number) << ctx;
  EXPECT_EQ(a.command, b.command) << ctx;
  EXPECT_EQ(a.command_status, b.command_status) << ctx;
  EXPECT_EQ(a.free_slots, b.free_slots) << ctx;
  EXPECT_EQ(a.message_count, b.message_count) << ctx;
  EXPECT_EQ(a.m_func_count, b.m_func_count) << ctx;
  EXPECT_EQ(a.m_func_line, b.m_func_line) << ctx;
  EXPECT_EQ(a.program_stop, b.program_stop) << ctx;
  EXPECT_EQ(a.limit_factor, b.limit_factor) << ctx;
  EXPECT_EQ(a.rel_speed, b.rel_speed) << ctx;
  EXPECT_EQ(a.set_speed, b.set_speed) << ctx;
  EXPECT_EQ(a.act_speed, b.act_speed) << ctx;
  EXPECT_EQ(a.act_acceleration_mm_s2, b.act_acceleration_mm_s2) << ctx;
  EXPECT_EQ(a.move_distance, b.move_distance) << ctx;
  EXPECT_EQ(a.orig_position, b.orig_position) << ctx;
  EXPECT_EQ(a.position, b.position) << ctx;
  EXPECT_EQ(a.position_inc, b.position_inc) << ctx;
  EXPECT_EQ(a.speed, b.speed) << ctx;
  EXPECT_EQ(a.backlash, b.backlash) << ctx;
  EXPECT_EQ(a.spline_deviation_mm, b.spline_deviation_mm) << ctx;
  EXPECT_EQ(a.m_function_parameter, b.m_function_parameter) << ctx;
  for (std::size_t e = 0; e < a.lookahead.size(); ++e) {
    const LookAheadEntry& x = a.lookahead[e];
    const LookAheadEntry& y = b.lookahead[e];
    EXPECT_EQ(x.movement_type, y.movement_type) << ctx << " entry " << e;
    EXPECT_EQ(x.movement_code, y.movement_code) << ctx << " entry " << e;
    EXPECT_EQ(x.line, y.line) << ctx << " entry " << e;
    EXPECT_EQ(x.tangent_deg, y.tangent_deg) << ctx << " entry " << e;
    EXPECT_EQ(x.end_pos_mm, y.end_pos_mm) << ctx << " entry " << e;
    EXPECT_EQ(x.all_params, y.all_params) << ctx << " entry " << e;
  }
}

}  // namespace tgm::test
