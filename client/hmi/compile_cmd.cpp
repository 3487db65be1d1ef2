// tgm-hmi compile: G-code text -> binary intercode and/or a dump.
#include <array>
#include <cstdint>
#include <cstdio>
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
    "                            [--out FILE] [--start X..,Y..] [--block-delete run|skip]\n"
    "\n"
    "Compiles a G-code program (FILE; - reads standard input) into intercode for interpolator N\n"
    "(default 0). Given intercode (what --out writes), it checks it and dumps it, copies it or\n"
    "sums it up.\n"
    "  --config YAML     machine config (default: $TGM_CONFIG, the installed\n"
    "                    or the in-tree config/default.yaml)\n"
    "  --interpolator N  which interpolator's axes and letters to compile for: 0 up\n"
    "                    to the config's interpolators - 1 (at most 2; default 0)\n"
    "  --dump jsonl      print one JSON object per record to standard output\n"
    "  --dump text       print one readable line per record\n"
    "  --out FILE        write the binary intercode to FILE (only when there is no error;\n"
    "                    '-' is standard output, as simulate's --csv -)\n"
    "  --start X20,Y5    where the machine will stand when the program starts [mm] (default:\n"
    "                    zero; axes not named: 0): G91 moves and the axes a G90 line does not\n"
    "                    name start there. The file records it, and `tgm-hmi run` runs the\n"
    "                    file only from there (`tgm-hmi run` compiles G-code from where the\n"
    "                    interpolator stands by itself)\n"
    "  --block-delete W  lines that start with '/' (optional blocks): run (the block delete\n"
    "                    switch off) or skip (on); default: the config's\n"
    "                    compiler.block_delete, error unless set (such a line is refused)\n"
    "\n"
    "Errors go to standard error as FILE:LINE:COL: error: reason, all of them; the exit\n"
    "code is then 2 and nothing is written.\n";

// Intercode encoded as the records come and written to `out` (when open) in 1 MiB pieces: a
// long program is never held whole. Nothing replaces `out` until commit().
class StreamedIntercode {
 public:
  StreamedIntercode(AtomicFile& out, const std::string& letters,
                    const std::array<double, kMaxAxes>& start_mm)
      : out_(out),
        encoder_(bytes_, static_cast<int>(letters.size()), letters, start_mm, /*streaming=*/true) {}
  void add(const Segment& s) {
    encoder_.add(s);
    if (bytes_.size() >= kPiece) flush();
  }
  std::uint64_t records() const { return encoder_.records(); }
  // Appends the tables, writes what is left and the record count, and commits `out`.
  bool commit(const std::vector<MParams>& params, const std::vector<std::string>& messages,
              std::string& error) {
    if (!out_.is_open()) return true;
    const std::uint64_t count = encoder_.records();
    encoder_.finish(params, messages);
    flush();
    if (!ok_) {
      error = error_;
      return false;
    }
    return out_.patch(static_cast<long>(IntercodeEncoder::kCountOffset), &count, sizeof count,
                      error) &&
           out_.commit(error);
  }

 private:
  static constexpr std::size_t kPiece = 1u << 20;
  void flush() {
    if (out_.is_open() && ok_) ok_ = out_.write(bytes_.data(), bytes_.size(), error_);
    bytes_.clear();
  }
  AtomicFile& out_;
  std::string bytes_;
  IntercodeEncoder encoder_;
  bool ok_ = true;
  std::string error_;
};

// Dumps every record to standard output a megabyte at a time: the dump of a program of
// millions of lines was built whole first (2 GB for 6 million, and nothing for `| head` to read
// until all of it was made).
bool dump_records(const PackedProgram& program, const std::string& dump) {
  std::string s;
  s.reserve((1u << 20) + 4096);
  auto cursor = program.cursor();
  Segment seg;
  const bool jsonl = dump == "jsonl";
  while (cursor.next(seg)) {
    if (jsonl) {
      dump_jsonl_record(program.tables(), seg, s);
    } else {
      dump_text_record(program.tables(), seg, s);
    }
    if (s.size() >= (1u << 20)) {
      if (!write_stdout(s, "compile", "the dump")) return false;
      s.clear();
    }
  }
  return write_stdout(s, "compile", "the dump");
}

// FILE is intercode already (`compile --out` wrote it, whatever its name now): checked as `run`
// and `simulate` check it, then dumped, written to --out (encoded anew: a file of an older
// version comes out in the current one) or summed up. It used to be lexed as G-code: 277
// errors of binary garbage.
int inspect_intercode(Args& args, const std::string& file, const FileView& input,
                      const std::string& dump, const std::string& out_path,
                      const std::string& start_text) {
  if (!start_text.empty()) {
    return args.usage_error("--start applies to G-code; " + file +
                            " is intercode, which records the point it was compiled from");
  }
  PackedProgram program;
  // M-functions and messages counted by record as the open checks them (records with equal
  // parameters or texts share one table entry).
  std::size_t ms = 0, texts = 0;
  if (!open_intercode(file, input, program, [&](const Segment& s) {
        ms += s.type == SegmentType::kMFunction;
        texts += s.type == SegmentType::kMessage;
      })) {
    return 2;
  }
  const Program& tables = program.tables();
  if (!out_path.empty()) {
    std::string io_error;
    AtomicFile out;
    if (!out.open(out_path, io_error))
      return args.usage_error("--out " + out_path + ": " + io_error);
    StreamedIntercode copy(out, tables.axis_letters, tables.start_mm);
    auto cursor = program.cursor();
    Segment seg;
    while (cursor.next(seg)) copy.add(seg);
    if (!copy.commit(tables.params, tables.messages, io_error)) {
      std::fprintf(stderr, "%s: error: %s\n", out_path.c_str(), io_error.c_str());
      return 1;
    }
  }
  if (!dump.empty()) {
    if (!dump_records(program, dump)) return 1;
  } else {
    const std::uint64_t records = program.size();
    std::fprintf(
        stderr,
        "%s: intercode for the axes %s, compiled from %s: %llu record%s (%zu M-function%s, "
        "%zu message%s)%s%s\n",
        file.c_str(), tables.axis_letters.c_str(),
        point_text(tables.start_mm, tables.axis_letters).c_str(),
        static_cast<unsigned long long>(records), records == 1 ? "" : "s", ms, ms == 1 ? "" : "s",
        texts, texts == 1 ? "" : "s", out_path.empty() ? "" : " written to ", out_path.c_str());
  }
  ProgramNotes notes;
  auto cursor = program.cursor();
  for (Segment seg; !notes.complete() && cursor.next(seg);) notes.observe(seg);
  notes.print(file, true);
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
    if (args.compile_flag()) continue;
    if (args.positional(file)) continue;
    return args.fail();
  }
  if (args.help()) return 0;
  if (args.failed()) return 2;
  if (file.empty()) return args.usage_error("a G-code FILE is required");
  // '-' is standard output, as `simulate --csv -` has it: it wrote a file named '-' (session
  // 75). Written there whole at the end (AtomicFile holds what goes to a pipe or a device).
  if (out_path == "-") {
    if (!dump.empty()) {
      return args.usage_error("--out - and --dump both write standard output: give --out a file");
    }
    out_path = "/dev/stdout";
  }
  if (!args.distinct_files({{"FILE", file}, args.config_file()}, {{"--out", out_path}})) {
    return 2;
  }
  if (!dump.empty() && dump != "jsonl" && dump != "text") {
    return args.usage_error("--dump takes jsonl or text, not '" + dump + "'");
  }
  const auto machine = args.load_machine();
  if (!machine) return 2;

  FileView input;
  if (!input.open_or_report(file)) return 2;
  const std::string_view text = input.text();
  const bool intercode = is_intercode(file, text);
  if (!args.compile_flags_fit(file, intercode)) return 2;
  if (intercode) return inspect_intercode(args, file, input, dump, out_path, start_text);
  CompileOptions options = CompileOptions::from_machine(*machine, args.interpolator());
  if (std::string why; !start_text.empty() &&
                       !parse_start(start_text, options.axis_letters, options.start_mm, why)) {
    return args.usage_error("--start: " + why);
  }

  // Without a dump the records are encoded as they come and written out in 1 MiB pieces: a long
  // program is never held in memory. With one they are held as intercode (about 20 bytes a
  // record), and dumped a piece at a time once the whole program compiled. The output only
  // replaces --out when there is no error.
  AtomicFile out;
  std::string io_error;
  if (!out_path.empty() && !out.open(out_path, io_error)) {
    return args.usage_error("--out " + out_path + ": " + io_error);
  }
  ProgramNotes notes(machine->tools);
  const auto note = [&](const Segment& s) { notes.observe(s); };
  // After the diagnostics themselves: their number, and the exit code of a program with errors.
  const auto no_intercode = [&](std::size_t errors) {
    std::fprintf(stderr, "%s: %zu error%s, no intercode written\n", file.c_str(), errors,
                 errors == 1 ? "" : "s");
    return 2;
  };
  // A program of comments and settings alone compiled "0 records", which simulate and run
  // then refused (session 75): refused here, as they refuse it.
  const auto no_records = [&] {
    std::fprintf(stderr,
                 "%s: error: the program has no records (no move, dwell or M-function): no "
                 "intercode written\n",
                 file.c_str());
    return 2;
  };
  if (!dump.empty()) {
    PackedProgram program;
    if (std::size_t errors = 0; !compile_packed(file, input, options, program, note, &errors)) {
      // Said: a file that changed while it was read (bad input), or an internal error.
      if (std::string why; errors == 0) return input.check(why) ? 1 : 2;
      return no_intercode(errors);
    }
    if (program.size() == 0) return no_records();
    if (out.is_open() && (!out.write(program.file().data(), program.file().size(), io_error) ||
                          !out.commit(io_error))) {
      std::fprintf(stderr, "%s: error: %s\n", out_path.c_str(), io_error.c_str());
      return 1;
    }
    if (!dump_records(program, dump)) return 1;
    notes.print(file);
    return 0;
  }
  StreamedIntercode streamed(out, options.axis_letters, options.start_mm);
  std::size_t ms = 0, texts = 0;  // by record: equal parameters or texts share a table entry
  const CompileResult result = compile_gcode(text, options, [&](const Segment& s) {
    streamed.add(s);
    note(s);
    ms += s.type == SegmentType::kMFunction;
    texts += s.type == SegmentType::kMessage;
  });
  // Changed under the compiler: nothing is written, and the diagnostics may be about a mix of
  // two versions of the file.
  if (!input.check_or_report(file)) return 2;
  if (!result.ok()) {
    print_compile_errors(file, result);
    return no_intercode(result.error_count());
  }
  if (streamed.records() == 0) return no_records();
  if (!streamed.commit(result.program.params, result.program.messages, io_error)) {
    std::fprintf(stderr, "%s: error: %s\n", out_path.c_str(), io_error.c_str());
    return 1;
  }
  const auto records = static_cast<unsigned long long>(streamed.records());
  const std::string from =
      start_text.empty() ? std::string()
                         : ", compiled from " + point_text(options.start_mm, options.axis_letters);
  std::fprintf(stderr, "%s: %llu record%s (%zu M-function%s, %zu message%s%s)%s%s\n", file.c_str(),
               records, records == 1 ? "" : "s", ms, ms == 1 ? "" : "s", texts,
               texts == 1 ? "" : "s", from.c_str(), out_path.empty() ? "" : " written to ",
               out_path.c_str());
  notes.print(file);
  return 0;
}

}  // namespace tgm::hmi
