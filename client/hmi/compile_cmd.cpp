// tgm-hmi compile: G-code text -> binary intercode and/or a dump.
#include <cstdint>
#include <cstdio>
#include <optional>
#include <string>
#include <string_view>

#include "cli_common.hpp"
#include "commands.hpp"
#include "tgm/gcode.hpp"
#include "tgm/intercode_io.hpp"

namespace tgm::hmi {

namespace {

constexpr const char* kUsage =
    "usage: tgm-hmi compile FILE [--config YAML] [--interpolator N] [--dump jsonl|text]\n"
    "                            [--out FILE] [--start X..,Y..]\n"
    "\n"
    "Compiles a G-code program into intercode for interpolator N (default 0). Given\n"
    "intercode (what --out writes), it checks it and dumps it, copies it or sums it up.\n"
    "  --config YAML     machine config (default: $TGM_CONFIG or config/default.yaml)\n"
    "  --interpolator N  which interpolator's axes and letters to compile for (0..2)\n"
    "  --dump jsonl      print one JSON object per record to standard output\n"
    "  --dump text       print one readable line per record\n"
    "  --out FILE        write the binary intercode to FILE (only when there is no error)\n"
    "  --start X20,Y5    where the machine will stand when the program starts [mm] (default:\n"
    "                    zero; axes not named: 0): G91 moves and the axes a G90 line does not\n"
    "                    name start there. The file records it, and `tgm-hmi run` runs the\n"
    "                    file only from there (`tgm-hmi run` compiles G-code from where the\n"
    "                    interpolator stands by itself)\n"
    "\n"
    "Errors go to standard error as FILE:LINE:COL: error: reason, all of them; the exit\n"
    "code is then 2 and nothing is written.\n";

// FILE is intercode already (`compile --out` wrote it, whatever its name now): decoded with
// the checks `run` and `simulate` make, then dumped, written to --out (a checked copy) or
// summed up. It used to be lexed as G-code: 277 errors of binary garbage.
int inspect_intercode(Args& args, const std::string& file, std::string_view text,
                      const std::string& dump, const std::string& out_path,
                      const std::string& start_text) {
  if (!start_text.empty()) {
    return args.usage_error("--start applies to G-code; " + file +
                            " is intercode, which records the point it was compiled from");
  }
  Program program;
  if (std::string why; !decode_intercode(text, program, why)) {
    std::fprintf(stderr, "%s: error: %s\n", file.c_str(), why.c_str());
    return 2;
  }
  if (!out_path.empty()) {
    std::string bytes, io_error;
    encode_intercode(program, bytes);
    AtomicFile out;
    if (!out.open(out_path, io_error) || !out.write(bytes.data(), bytes.size(), io_error) ||
        !out.commit(io_error)) {
      std::fprintf(stderr, "%s: error: %s\n", out_path.c_str(), io_error.c_str());
      return 1;
    }
  }
  if (!dump.empty()) {
    std::string s;
    if (dump == "jsonl") {
      dump_jsonl(program, s);
    } else {
      dump_text(program, s);
    }
    if (!write_stdout(s, "compile", "the dump")) return 1;
  } else {
    const std::size_t records = program.segments.size(), ms = program.params.size(),
                      texts = program.messages.size();
    std::fprintf(stderr,
                 "%s: intercode for the axes %s, compiled from %s: %zu record%s (%zu M-function%s, "
                 "%zu message%s)%s%s\n",
                 file.c_str(), program.axis_letters.c_str(),
                 point_text(program.start_mm, program.axis_letters).c_str(), records,
                 records == 1 ? "" : "s", ms, ms == 1 ? "" : "s", texts, texts == 1 ? "" : "s",
                 out_path.empty() ? "" : " written to ", out_path.c_str());
  }
  CompensationNote compensation;
  compensation.observe(program);
  compensation.print(file);
  return 0;
}

}  // namespace

int run_compile(int argc, char** argv) {
  Args args(argc, argv, "compile", kUsage);
  std::string dump;
  std::string out_path;
  std::string file, start_text;
  while (args.more()) {
    if (args.flag("--dump", dump)) continue;
    if (args.flag("--out", out_path)) continue;
    if (args.flag("--start", start_text)) continue;
    if (args.common()) continue;
    if (args.positional(file)) continue;
    return args.fail();
  }
  if (args.help()) return 0;
  if (args.failed()) return 2;
  if (file.empty()) return args.usage_error("a G-code FILE is required");
  if (!args.distinct_files({{"FILE", file}, args.config_file()}, {{"--out", out_path}})) {
    return 2;
  }
  if (!dump.empty() && dump != "jsonl" && dump != "text") {
    return args.usage_error("--dump takes jsonl or text, not '" + dump + "'");
  }
  const auto machine = args.load_machine();
  if (!machine) return 2;

  FileView input;
  if (std::string err; !input.open(file, err)) {
    std::fprintf(stderr, "%s: error: %s\n", file.c_str(), err.c_str());
    return 2;
  }
  const std::string_view text = input.text();
  if (is_intercode(file, text))
    return inspect_intercode(args, file, text, dump, out_path, start_text);
  CompileOptions options = CompileOptions::from_machine(*machine, args.interpolator());
  if (std::string why; !start_text.empty() &&
                       !parse_start(start_text, options.axis_letters, options.start_mm, why)) {
    return args.usage_error("--start: " + why);
  }

  // Without a dump the records are encoded as they come and written out in 1 MiB pieces: a long
  // program is never held in memory. The output only replaces --out when there is no error.
  AtomicFile out;
  std::string io_error;
  if (!out_path.empty() && !out.open(out_path, io_error)) {
    std::fprintf(stderr, "%s: error: %s\n", out_path.c_str(), io_error.c_str());
    return 1;
  }
  std::string bytes;
  std::optional<IntercodeEncoder> encoder;
  CompileResult result;
  CompensationNote compensation;
  bool write_ok = true;
  if (dump.empty()) {
    bytes.reserve(2u << 20);
    encoder.emplace(bytes, static_cast<int>(options.axis_letters.size()), options.axis_letters,
                    options.start_mm, /*streaming=*/true);
    result = compile_gcode(text, options, [&](const Segment& s) {
      encoder->add(s);
      compensation.observe(s);
      if (bytes.size() >= (1u << 20)) {
        if (out.is_open() && write_ok) write_ok = out.write(bytes.data(), bytes.size(), io_error);
        bytes.clear();
      }
    });
  } else {
    result = compile_gcode(text, options);
    compensation.observe(result.program);
  }
  if (!result.ok()) {
    for (const Diagnostic& d : result.errors) {
      std::fprintf(stderr, "%s\n", format_diagnostic(file, d).c_str());
    }
    std::fprintf(stderr, "%s: %zu error%s, no intercode written\n", file.c_str(),
                 result.error_count(), result.error_count() == 1 ? "" : "s");
    return 2;
  }
  if (out.is_open()) {
    if (encoder) {
      const std::uint64_t count = encoder->records();
      encoder->finish(result.program.params, result.program.messages);
      write_ok = write_ok && out.write(bytes.data(), bytes.size(), io_error) &&
                 out.patch(static_cast<long>(IntercodeEncoder::kCountOffset), &count,
                           sizeof count, io_error);
    } else {
      encode_intercode(result.program, bytes);
      write_ok = out.write(bytes.data(), bytes.size(), io_error);
    }
    if (!write_ok || !out.commit(io_error)) {
      std::fprintf(stderr, "%s: error: %s\n", out_path.c_str(), io_error.c_str());
      return 1;
    }
  }
  if (!dump.empty()) {
    std::string s;
    if (dump == "jsonl") {
      dump_jsonl(result.program, s);
    } else {
      dump_text(result.program, s);
    }
    if (!write_stdout(s, "compile", "the dump")) return 1;
  }
  if (dump.empty()) {
    const unsigned long long records = encoder->records();
    const std::size_t ms = result.program.params.size(), texts = result.program.messages.size();
    const std::string from =
        start_text.empty()
            ? std::string()
            : ", compiled from " + point_text(options.start_mm, options.axis_letters);
    std::fprintf(stderr, "%s: %llu record%s (%zu M-function%s, %zu message%s%s)%s%s\n",
                 file.c_str(), records, records == 1 ? "" : "s", ms, ms == 1 ? "" : "s", texts,
                 texts == 1 ? "" : "s", from.c_str(), out_path.empty() ? "" : " written to ",
                 out_path.c_str());
  }
  compensation.print(file);
  return 0;
}

}  // namespace tgm::hmi
