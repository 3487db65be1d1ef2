// Time stamps on the log lines of tgm-service and tgm-plc (tgm/log_time.hpp): the stamp's
// format, the stamping of text written in pieces, and when "auto" stamps.
#include "tgm/log_time.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <ctime>
#include <string>

namespace tgm {
namespace {

using std::chrono::system_clock;

// TZ for the length of one test.
class LocalZone {
 public:
  explicit LocalZone(const char* zone) {
    if (const char* old = std::getenv("TZ")) old_ = old;
    ::setenv("TZ", zone, 1);
    ::tzset();
  }
  ~LocalZone() {
    if (old_.empty()) {
      ::unsetenv("TZ");
    } else {
      ::setenv("TZ", old_.c_str(), 1);
    }
    ::tzset();
  }

 private:
  std::string old_;
};

TEST(LogTime, StampIsLocalDateAndTimeToTheMillisecondWithTheOffset) {
  // 2026-12-05 12:20:01.123456 UTC.
  const auto t = system_clock::from_time_t(1796473201) + std::chrono::microseconds(123456);
  {
    LocalZone utc("UTC0");  // POSIX zones: no tzdata needed
    EXPECT_EQ(log_stamp(t), "2026-12-05 12:20:01.123+0000 ");
    EXPECT_EQ(log_stamp(system_clock::from_time_t(1796473201)), "2026-12-05 12:20:01.000+0000 ");
    EXPECT_EQ(log_stamp(t + std::chrono::milliseconds(877)), "2026-12-05 12:20:02.000+0000 ");
  }
  LocalZone cet("CET-1");  // one hour east of UTC
  EXPECT_EQ(log_stamp(t), "2026-12-05 13:20:01.123+0100 ");
}

TEST(LogTime, EveryLineIsStampedOnceAlsoWhenWrittenInPieces) {
  LineStamper s;
  EXPECT_EQ(s.add("tgm-service: one\ntgm-service: tw", "[1] "),
            "[1] tgm-service: one\n[1] tgm-service: tw");
  EXPECT_EQ(s.add("o\n", "[2] "), "o\n");  // the line began in the piece before
  EXPECT_EQ(s.add("", "[3] "), "");
  EXPECT_EQ(s.add("\n\nthree", "[4] "), "[4] \n[4] \n[4] three");
  EXPECT_EQ(s.add("\n", "[5] "), "\n");
  EXPECT_EQ(s.add("x", "[6] "), "[6] x");
}

TEST(LogTime, AutoStampsUnlessTheOutputIsTheJournal) {
  EXPECT_TRUE(log_time_wanted(LogTime::kAuto, nullptr, "8:1234"));
  EXPECT_FALSE(log_time_wanted(LogTime::kAuto, "8:1234", "8:1234"));
  // Inherited from a service started by systemd, but redirected elsewhere by hand.
  EXPECT_TRUE(log_time_wanted(LogTime::kAuto, "8:1234", "8:99"));
  EXPECT_TRUE(log_time_wanted(LogTime::kAuto, "8:1234", ""));
  EXPECT_TRUE(log_time_wanted(LogTime::kOn, "8:1234", "8:1234"));
  EXPECT_FALSE(log_time_wanted(LogTime::kOff, nullptr, "8:1234"));
}

TEST(LogTime, ParsesItsThreeWords) {
  EXPECT_EQ(parse_log_time("auto"), LogTime::kAuto);
  EXPECT_EQ(parse_log_time("on"), LogTime::kOn);
  EXPECT_EQ(parse_log_time("off"), LogTime::kOff);
  EXPECT_FALSE(parse_log_time("yes"));
  EXPECT_FALSE(parse_log_time(""));
  EXPECT_FALSE(parse_log_time("On"));
}

}  // namespace
}  // namespace tgm
