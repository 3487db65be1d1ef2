// tgm_bench_stream: program streaming rate into a running tgm-service. Streams a program of N
// plain G1 records into interpolator 0 (whose Buffer_Size must hold them) with the client
// library's flow control, timed from the first chunk written until the service confirms the last
// record (InterpolatorState.next_sequence), then clears; K runs.
//
//   tgm_bench_stream --config YAML [DDS overrides] [--records N] [--runs K]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <optional>
#include <string>
#include <vector>

#include "tgm/cli_args.hpp"
#include "tgm/client/client.hpp"
#include "tgm/dds_overrides.hpp"
#include "tgm/yaml_config.hpp"

namespace {
constexpr const char* kUsage =
    "usage: tgm_bench_stream [--config YAML] [DDS overrides] [--records N] [--runs K]\n"
    "Streams N plain G1 records into interpolator 0 of a running tgm-service K times and prints\n"
    "the rate of each run and the median (BENCHMARKS.md, section Service).\n"
    "  --config YAML   the service's config (default: config/default.yaml); interpolator 0's\n"
    "                  Buffer_Size must hold the N records\n"
    "  --domain, --profiles, --participant-prefix, --security: as tgm-hmi's\n"
    "  --records N     records per run, 1..100000 (default 100000)\n"
    "  --runs K        runs, 1..1000 (default 5)\n";
}  // namespace

int main(int argc, char** argv) {
  using namespace std::chrono_literals;
  std::string config_path;
  tgm::DdsOverrides overrides;
  long long records_flag = 100'000;
  int runs = 5;
  tgm::cli::ArgReader args(argc, argv, "tgm_bench_stream");
  while (args.more()) {
    if (args.help_flag()) {
      std::fputs(kUsage, stdout);
      return 0;
    }
    if (args.flag("--config", config_path) || args.dds_flag(overrides) ||
        args.whole_flag("--records", 1LL, 100'000LL, records_flag) ||
        args.whole_flag("--runs", 1, 1000, runs)) {
      continue;
    }
    return args.fail();
  }
  if (args.failed()) return 2;
  const auto records = static_cast<std::size_t>(records_flag);
  std::optional<tgm::AppConfig> config =
      tgm::load_config_or_report(config_path, "tgm_bench_stream");
  if (!config) return 2;
  overrides.apply(config->dds);
  tgm::Program program;
  program.number_axes = static_cast<int>(config->machine.interpolators[0].axes.size());
  program.axis_letters = config->machine.axis_letters(0);
  for (std::size_t i = 0; i < records; ++i) {
    tgm::Segment s;
    s.line = static_cast<std::int32_t>(i + 1);
    s.end[0] = 0.01 * static_cast<double>(i + 1);
    s.feed_mm_per_min = 6000;
    program.segments.push_back(s);
  }
  tgm::client::Client hmi(config->dds, tgm::client::Role::kHmi);
  if (!hmi.wait_for_state(0, 10s)) {
    std::fprintf(stderr, "tgm_bench_stream: no tgm-service\n");
    return 1;
  }
  if (static_cast<std::size_t>(hmi.state(0)->buffer_size()) < records) {
    std::fprintf(stderr, "tgm_bench_stream: Buffer_Size %d < %zu records\n", hmi.state(0)->buffer_size(), records);
    return 2;
  }
  std::vector<double> rates;
  for (int run = 0; run < runs; ++run) {
    hmi.clear(0);
    hmi.wait_until(0, [](const tgm::msg::InterpolatorState& s) { return s.status() == 0; }, 5s);
    tgm::client::ProgramSender sender(hmi, program, 0, tgm::client::new_program_id());
    const auto t0 = std::chrono::steady_clock::now();
    while (!sender.all_confirmed()) {
      if (!sender.pump()) {
        std::fprintf(stderr, "tgm_bench_stream: %s\n", sender.error().c_str());
        return 1;
      }
      hmi.poll(200us);
      if (std::chrono::steady_clock::now() - t0 > 120s) return 1;
    }
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    rates.push_back(static_cast<double>(records) / s);
    std::printf("run %d: %zu records in %.3f s = %.0f records/s\n", run + 1, records, s, rates.back());
  }
  hmi.clear(0);
  std::sort(rates.begin(), rates.end());
  std::printf("median %.0f records/s (min %.0f, max %.0f) over %d runs\n", rates[rates.size() / 2], rates.front(),
              rates.back(), runs);
  return 0;
}
