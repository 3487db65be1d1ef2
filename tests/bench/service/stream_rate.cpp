// tgm_bench_stream: program streaming rate into a running tgm-service. Streams a program of N
// plain G1 records into interpolator 0 (whose Buffer_Size must hold them) with the client
// library's flow control, timed from the first chunk written until the service confirms the last
// record (InterpolatorState.next_sequence), then clears; K runs.
//
//   tgm_bench_stream --config YAML [--domain D] [--records N] [--runs K]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "tgm/client/client.hpp"
#include "tgm/yaml_config.hpp"

int main(int argc, char** argv) {
  using namespace std::chrono_literals;
  std::string config_path;
  int domain = -1;
  std::size_t records = 100'000;
  int runs = 5;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--config") config_path = argv[i + 1];
    else if (a == "--domain") domain = std::atoi(argv[i + 1]);
    else if (a == "--records") records = static_cast<std::size_t>(std::atol(argv[i + 1]));
    else if (a == "--runs") runs = std::atoi(argv[i + 1]);
    else return 2;
  }
  tgm::ConfigLoad load = tgm::load_config_file(config_path.empty() ? tgm::default_config_path() : config_path);
  if (!load.config) return 2;
  if (domain >= 0) load.config->dds.domain_id = domain;
  tgm::Program program;
  program.number_axes = static_cast<int>(load.config->machine.interpolators[0].axes.size());
  program.axis_letters = load.config->machine.axis_letters(0);
  for (std::size_t i = 0; i < records; ++i) {
    tgm::Segment s;
    s.line = static_cast<std::int32_t>(i + 1);
    s.end[0] = 0.01 * static_cast<double>(i + 1);
    s.feed_mm_per_min = 6000;
    program.segments.push_back(s);
  }
  tgm::client::Client hmi(load.config->dds, tgm::client::Role::kHmi);
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
