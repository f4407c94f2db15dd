// A regression suite of scenarios: discovery, the runs, verdicts, the lines and JUnit XML (suite.hpp).
#include "cellwright/cell/suite.hpp"

#include <unistd.h>

#include <yaml-cpp/yaml.h>

#include <fmt/format.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <set>
#include <thread>

#include "cellwright/common/error.hpp"
#include "cellwright/common/files.hpp"
#include "cellwright/common/xml.hpp"
#include "cellwright/models/yaml_fields.hpp"
#include "cellwright/runtime/recovery.hpp"
#include "cellwright/cell/campaign.hpp"
#include "cellwright/cell/outputs.hpp"

namespace cellwright::cell {

namespace fs = std::filesystem;

// --- Discovery -------------------------------------------------------------------------------------------------------

namespace {

bool is_list(const YAML::Node& map, const char* key) {
  const YAML::Node n = map[key];
  return n.IsDefined() && n.IsSequence();
}

// A number field of a mapping, or 0.
double number_or_zero(const YAML::Node& map, const char* key) {
  if (!map.IsDefined() || !map.IsMap()) return 0;  // a missing key's node is invalid: only IsDefined() may be asked
  const YAML::Node n = map[key];
  if (!n.IsDefined() || !n.IsScalar()) return 0;
  try {
    return n.as<double>();
  } catch (const YAML::Exception&) {
    return 0;
  }
}

}  // namespace

YamlClass classify_yaml(const fs::path& file) {
  const std::string text = read_file(file);
  const models::yaml::Doc doc(file.string());
  const YAML::Node root = models::yaml::load(text, doc, "not valid YAML");
  YamlClass c;
  if (!root.IsMap()) {
    c.what = root.IsSequence() ? "a list" : root.IsScalar() ? "a single value" : "empty";
    return c;
  }
  if (root["cell"].IsDefined() && root["program"].IsDefined()) {
    c.kind = YamlKind::kScenario;
    c.what = "a scenario";
    c.wall_time = std::max(0.0, number_or_zero(root["limits"], "wall_time"));
    return c;
  }
  bool all_symptoms = root.size() > 0;
  for (const auto& kv : root) {
    all_symptoms = all_symptoms && kv.first.IsScalar() && runtime::symptom_from(kv.first.Scalar()).has_value();
  }
  if (all_symptoms) {
    c.kind = YamlKind::kDecisionTree;
    c.what = "a decision tree (docs/faults.md)";
    return c;
  }
  if (is_list(root, "robots") || is_list(root, "workpieces") || is_list(root, "conveyors") ||
      is_list(root, "machines")) {
    c.kind = YamlKind::kCell;
    c.what = "a cell description (docs/cell-description.md)";
    return c;
  }
  c.what = "a mapping without the fields `cell` and `program`";
  return c;
}

namespace {

bool yaml_name(const fs::path& p) {
  const std::string ext = p.extension().string();
  return ext == ".yaml" || ext == ".yml";
}

}  // namespace

Discovery discover(const std::vector<fs::path>& paths) {
  Discovery d;
  std::set<fs::path> seen;  // canonical paths of the scenarios found
  auto add = [&](const fs::path& p, double wall_time, std::string error) {
    std::error_code ec;
    fs::path key = fs::weakly_canonical(p, ec);
    if (ec) key = fs::absolute(p);
    if (seen.insert(key).second) d.scenarios.push_back({p, wall_time, std::move(error)});
  };
  // What the file is; nullopt when it cannot be read or parsed: then it is added as a case with that error.
  auto classify = [&](const fs::path& p) -> std::optional<YamlClass> {
    try {
      return classify_yaml(p);
    } catch (const InputError& e) {
      add(p, 0, e.what());
      return std::nullopt;
    }
  };
  for (const fs::path& p : paths) {
    std::error_code ec;
    const fs::file_status st = fs::status(p, ec);
    if (p.empty() || !fs::exists(st)) throw InputError({p.string(), 0, 0}, "no such file or folder");
    if (!fs::is_directory(st)) {
      const std::optional<YamlClass> c = classify(p);
      if (!c) continue;
      if (c->kind != YamlKind::kScenario) {
        throw InputError({p.string(), 0, 0},
                         fmt::format("not a scenario: {} (a scenario has the fields `cell` and `program`, "
                                     "docs/scenarios.md)",
                                     c->what));
      }
      add(p, c->wall_time, "");
      continue;
    }
    std::vector<fs::path> entries;
    fs::directory_iterator it(p, ec);
    for (; !ec && it != fs::directory_iterator(); it.increment(ec)) entries.push_back(it->path());
    if (ec) throw InputError({p.string(), 0, 0}, fmt::format("cannot read the folder: {}", ec.message()));
    std::sort(entries.begin(), entries.end());
    for (const fs::path& e : entries) {
      if (e.filename().string().front() == '.') continue;  // hidden: not the user's scenarios
      if (fs::is_directory(e, ec)) {
        d.skipped.push_back({e, "a subfolder (not entered unless named)"});
        continue;
      }
      if (!yaml_name(e)) continue;
      const std::optional<YamlClass> c = classify(e);
      if (!c) continue;
      if (c->kind == YamlKind::kScenario) {
        add(e, c->wall_time, "");
      } else {
        d.skipped.push_back({e, c->what + ", not a scenario"});
      }
    }
  }
  if (d.scenarios.empty()) {
    std::string where;
    for (const fs::path& p : paths) where += (where.empty() ? "" : ", ") + p.string();
    throw InputError({where, 0, 0},
                     "no scenario found (a scenario is a .yaml file with the fields `cell` and "
                     "`program`, docs/scenarios.md)");
  }
  return d;
}

// --- Planning --------------------------------------------------------------------------------------------------------

double default_timeout(double scenario_wall_time) {
  return scenario_wall_time > 0 ? scenario_wall_time + 60 : 600;
}

std::vector<SuiteCase> plan_suite(const Discovery& found, const fs::path& out, std::optional<double> timeout,
                                  bool force) {
  if (timeout && !(*timeout > 0)) {
    throw InputError({"--timeout", 0, 0}, fmt::format("must be > 0 s, not {}", *timeout));
  }
  check_writable_dir(out);
  std::vector<SuiteCase> cases;
  std::set<std::string> names;
  for (const FoundScenario& s : found.scenarios) {
    SuiteCase c;
    c.scenario = s.path;
    const std::string stem = s.path.stem().string();
    c.name = stem;
    for (int k = 2; names.count(c.name) != 0; ++k) c.name = fmt::format("{}-{}", stem, k);
    names.insert(c.name);
    c.dir = out / c.name;
    c.error = s.error;
    c.timeout = timeout ? *timeout : default_timeout(s.wall_time);
    cases.push_back(std::move(c));
  }
  // Each OUT/NAME, which a run empties: Cellwright's (marked, an earlier run's, or empty), or refused.
  for (const SuiteCase& c : cases) {
    std::error_code ec;
    if (force || !c.error.empty() || !fs::exists(c.dir, ec)) continue;
    const bool earlier_run =
        fs::is_directory(c.dir, ec) && (fs::exists(c.dir / kMarkerFile, ec) || fs::exists(c.dir / kChildStdout, ec) ||
                                        fs::is_empty(c.dir, ec));
    if (!earlier_run) {
      throw InputError({c.dir.string(), 0, 0},
                       fmt::format("exists and is not the outputs of an earlier run (it has no {}): the suite would "
                                   "replace it; give another -o/--output, or --force to replace it",
                                   kMarkerFile));
    }
  }
  return cases;
}

void check_writable_file(const fs::path& file) {
  std::error_code ec;
  if (file.empty() || fs::is_directory(file, ec)) throw InputError({file.string(), 0, 0}, "not a file name");
  const fs::path parent = file.has_parent_path() ? file.parent_path() : fs::path(".");
  check_writable_dir(parent);
  if (fs::exists(file, ec) && ::access(file.c_str(), W_OK) != 0) {
    throw InputError({file.string(), 0, 0}, fmt::format("cannot be written: {}", std::strerror(errno)));
  }
}

fs::path make_temporary_output_dir() {
  std::error_code ec;
  fs::path base = fs::temp_directory_path(ec);
  if (ec) base = "/tmp";
  std::string name = (base / "cellwright-test-XXXXXX").string();
  if (::mkdtemp(name.data()) == nullptr) {
    throw InputError({name, 0, 0}, fmt::format("cannot create the output folder: {}", std::strerror(errno)));
  }
  return name;
}

// --- Running ---------------------------------------------------------------------------------------------------------

const char* to_string(Verdict v) {
  switch (v) {
    case Verdict::kPass:
      return "pass";
    case Verdict::kFail:
      return "fail";
    case Verdict::kError:
      return "error";
    case Verdict::kCrash:
      return "crash";
    case Verdict::kHang:
      return "hang";
  }
  return "?";
}

namespace {

std::string slurp_or_empty(const fs::path& p) {
  try {
    return read_file(p);
  } catch (const InputError&) {
    return std::string();
  }
}

std::string first_line_of(const std::string& s) {
  return s.substr(0, s.find('\n'));
}

}  // namespace

CaseResult judge(const SuiteCase& test, const ChildEnd& end) {
  CaseResult r;
  r.test = test;
  r.end = end;
  r.output = slurp_or_empty(test.dir / kChildStdout);
  r.errors = slurp_or_empty(test.dir / kChildStderr);
  bool report_ok = false;
  if (end.report) {
    const Report& rep = *end.report;
    r.sim_time = rep.end_time;
    r.placed = rep.placed_at.size();
    r.failures = rep.failures;
    report_ok = rep.ok();
  }
  switch (end.status) {
    case RunStatus::kHang:
      r.verdict = Verdict::kHang;
      r.message = end.problem;
      break;
    case RunStatus::kCrash:
      if (end.signal == 0 && end.exit_code == 2) {  // `twin run` refused its input
        r.verdict = Verdict::kError;
        r.message = end.first_error.empty() ? end.problem : "refused: " + end.first_error;
      } else {
        r.verdict = Verdict::kCrash;
        r.message = end.problem;
      }
      break;
    case RunStatus::kDone:
      if (end.exit_code == 0 && report_ok) {
        r.verdict = Verdict::kPass;
      } else if (end.exit_code == 0 || end.exit_code == 1) {
        r.verdict = Verdict::kFail;
        if (!r.failures.empty()) {
          r.message = first_line_of(r.failures.front());
        } else {
          r.message = fmt::format("exit {}, outcome {}{}", end.exit_code, end.report->outcome,
                                  report_ok ? std::string(" (the report says ok)") : std::string());
        }
      } else {
        r.verdict = Verdict::kError;
        r.message =
            fmt::format("exit {}{}", end.exit_code, end.first_error.empty() ? std::string() : ": " + end.first_error);
      }
      break;
  }
  if (!r.passed() && r.failures.empty()) r.failures.push_back(r.message);
  return r;
}

std::string format_progress(const SuiteProgress& p, int width) {
  const int filled =
      p.total == 0
          ? 0
          : static_cast<int>(static_cast<double>(width) * static_cast<double>(p.done) / static_cast<double>(p.total));
  return fmt::format("[{}{}] {}/{} scenarios, {} running, {} failed", std::string(filled, '#'),
                     std::string(static_cast<std::size_t>(width - filled), '.'), p.done, p.total, p.running, p.failed);
}

namespace {

// `twin run SCENARIO -o DIR --quiet [EXTRA...] [--seed S]` for a case, its outputs in `dir`.
ChildSpec run_child(const SuiteCase& c, const fs::path& dir, const SuiteOptions& options,
                    const std::vector<std::string>& extra = {}) {
  ChildSpec spec;
  spec.args = {"run", fs::absolute(c.scenario).string(), "-o", dir.string(), "--quiet"};
  spec.args.insert(spec.args.end(), extra.begin(), extra.end());
  if (options.seed) {
    spec.args.push_back("--seed");
    spec.args.push_back(std::to_string(*options.seed));
  }
  spec.dir = dir;
  spec.timeout = c.timeout;
  return spec;
}

unsigned jobs_of(const SuiteOptions& options) {
  return options.jobs > 0 ? options.jobs : std::max(1u, std::thread::hardware_concurrency());
}

}  // namespace

std::vector<CaseResult> run_suite(const std::vector<SuiteCase>& cases, const SuiteOptions& options,
                                  const SuiteCallbacks& callbacks) {
  std::vector<ChildSpec> children;
  // final.png only for a failed scenario, whose outputs are kept, unless every scenario's outputs are kept.
  const std::vector<std::string> final_png =
      options.keep ? std::vector<std::string>{} : std::vector<std::string>{"--final-png", "failed"};
  std::vector<std::size_t> which;  // the case of each child
  for (std::size_t i = 0; i < cases.size(); ++i) {
    if (!cases[i].error.empty()) continue;
    children.push_back(run_child(cases[i], cases[i].dir, options, final_png));
    which.push_back(i);
  }
  std::vector<CaseResult> results(cases.size());
  SuiteProgress progress;
  progress.total = cases.size();
  auto report = [&] {
    if (callbacks.progress) callbacks.progress(progress);
  };
  // The files that could not be parsed: errors now, without a run.
  for (std::size_t i = 0; i < cases.size(); ++i) {
    if (cases[i].error.empty()) continue;
    CaseResult& r = results[i];
    r.test = cases[i];
    r.verdict = Verdict::kError;
    r.message = cases[i].error;
    r.failures = {r.message};
    r.kept = false;
    ++progress.done;
    ++progress.failed;
    if (callbacks.ended) callbacks.ended(r);
  }
  ChildCallbacks cb;
  cb.started = [&](std::size_t) {
    ++progress.running;
    report();
  };
  cb.ended = [&](std::size_t k, const ChildEnd& end) {
    const std::size_t i = which[k];
    CaseResult& r = results[i];
    r = judge(cases[i], end);
    if (r.passed() && !options.keep) {
      std::error_code ec;
      fs::remove_all(r.test.dir, ec);
      r.kept = fs::exists(r.test.dir, ec);
    }
    ++progress.done;
    --progress.running;
    if (!r.passed()) ++progress.failed;
    if (callbacks.ended) callbacks.ended(r);
    report();
  };
  report();
  run_children(options.executable, children, jobs_of(options), cb);
  return results;
}

// --- Videos of the failed scenarios --------------------------------------------------------------------------------

namespace {

constexpr const char* kVideoDir = ".video";  // DIR/.video: the re-run's outputs, removed once its video is moved
constexpr const char* kVideoFile = "video.mp4";
constexpr const char* kVideoPage = "video.html";      // the re-run's page, when it was another run than the first
constexpr const char* kVideoStderr = "video-stderr.txt";  // the re-run's stderr, when it made no video

// Whether two files hold the same bytes, read a block at a time (an event log may be large). False when either
// cannot be read.
bool same_bytes(const fs::path& a, const fs::path& b) {
  std::error_code ec1, ec2;
  const auto size_a = fs::file_size(a, ec1), size_b = fs::file_size(b, ec2);
  if (ec1 || ec2 || size_a != size_b) return false;
  std::ifstream fa(a, std::ios::binary), fb(b, std::ios::binary);
  if (!fa || !fb) return false;
  std::vector<char> ba(1 << 16), bb(1 << 16);
  while (fa && fb) {
    fa.read(ba.data(), static_cast<std::streamsize>(ba.size()));
    fb.read(bb.data(), static_cast<std::streamsize>(bb.size()));
    if (fa.gcount() != fb.gcount() || !std::equal(ba.begin(), ba.begin() + fa.gcount(), bb.begin())) return false;
  }
  return fa.eof() && fb.eof();
}

// fs::exists, false when it cannot tell (no exception: a failed look is a file not there).
bool present(const fs::path& p) {
  std::error_code ec;
  return fs::exists(p, ec);
}

// What went wrong with a re-run that made no video, one line.
std::string no_video_because(const ChildEnd& end, const fs::path& video) {
  if (end.status != RunStatus::kDone) return end.problem;
  if (!end.first_error.empty()) return end.first_error;
  if (!present(video)) return fmt::format("the re-run (exit {}) wrote no {}", end.exit_code, video.string());
  return fmt::format("the re-run ended with exit {}", end.exit_code);
}

// Moves the re-run's video (and its page) from `from` (DIR/.video) into the case's directory; sets r.video and
// r.video_note. Throws InputError as move_file.
void take_video(CaseResult& r, const fs::path& from) {
  move_file(from / kVideoFile, r.test.dir / kVideoFile);
  r.video = r.test.dir / kVideoFile;
  const bool same_run = same_bytes(from / kEventsFile, r.test.dir / kEventsFile);
  if (same_run) {
    if (present(from / kPageFile)) move_file(from / kPageFile, r.test.dir / kPageFile);
    return;
  }
  // Another run (a scenario in real time): the first run's page, report and pictures stay together; the re-run's
  // page, which shows the video with that run's verdict, goes beside them.
  r.video_note = fmt::format("the re-run's event log differs from the run's (a scenario in real time): the video "
                             "shows another run of it, with its page {}",
                             kVideoPage);
  if (present(from / kPageFile)) move_file(from / kPageFile, r.test.dir / kVideoPage);
}

}  // namespace

double video_timeout(const CaseResult& r, double slowdown) {
  return std::min(r.test.timeout * slowdown, std::max(60.0, r.end.wall_time * slowdown));
}

void record_videos(std::vector<CaseResult>& results, const SuiteOptions& options, const VideoSettings& video,
                   const VideoCallbacks& callbacks) {
  std::vector<std::size_t> which;  // indices into results
  std::vector<ChildSpec> children;
  for (std::size_t i = 0; i < results.size(); ++i) {
    const CaseResult& r = results[i];
    if (r.verdict != Verdict::kFail || !r.kept) continue;
    const fs::path dir = r.test.dir / kVideoDir;
    ChildSpec spec = run_child(r.test, dir, options,
                               {"--video", (dir / kVideoFile).string(), "--video-fps", std::to_string(video.fps),
                                "--video-size", video.size});
    spec.timeout = video_timeout(r, video.slowdown);
    which.push_back(i);
    children.push_back(std::move(spec));
  }
  if (children.empty()) return;
  std::size_t done = 0;
  auto progress = [&] {
    if (callbacks.progress) callbacks.progress(done, which.size());
  };
  ChildCallbacks cb;
  cb.ended = [&](std::size_t k, const ChildEnd& end) {
    CaseResult& r = results[which[k]];
    const fs::path dir = r.test.dir / kVideoDir;
    // exit 1 is the failure again; exit 0 would be a run that passed this time (only in real time): still a video.
    const bool made = end.status == RunStatus::kDone && (end.exit_code == 0 || end.exit_code == 1) &&
                      present(dir / kVideoFile);
    if (made) {
      try {
        take_video(r, dir);
      } catch (const InputError& e) {
        r.video_note = e.what();
      }
    } else {
      r.video_note = no_video_because(end, dir / kVideoFile);
      std::error_code ec;
      if (fs::file_size(dir / kChildStderr, ec) > 0 && !ec) {
        try {
          move_file(dir / kChildStderr, r.test.dir / kVideoStderr);
          r.video_note += fmt::format(" (its stderr in {})", (r.test.dir / kVideoStderr).string());
        } catch (const InputError&) {
          // the note has the first line already
        }
      }
    }
    std::error_code ec;
    fs::remove_all(dir, ec);
    ++done;
    if (callbacks.ended) callbacks.ended(r);
    progress();
  };
  cb.started = [&](std::size_t) { progress(); };
  progress();
  try {
    run_children(options.executable, children, jobs_of(options), cb);
  } catch (...) {  // the children were killed: no half-made re-run is left behind
    for (const ChildSpec& c : children) {
      std::error_code ec;
      fs::remove_all(c.dir, ec);
    }
    throw;
  }
}

// --- Reporting -------------------------------------------------------------------------------------------------------

namespace {

std::string upper(const char* s) {
  std::string u(s);
  for (char& c : u) c = static_cast<char>(c >= 'a' && c <= 'z' ? c - 'a' + 'A' : c);
  return u;
}

// `s` with every character XML 1.0 does not allow (control characters other than tab, newline and carriage return;
// U+FFFE, U+FFFF) and every byte that is not part of well-formed UTF-8 replaced by U+FFFD.
std::string xml_safe(std::string_view s) {
  static constexpr std::string_view kReplacement = "\xEF\xBF\xBD";
  std::string out;
  out.reserve(s.size());
  const auto byte = [&](std::size_t i) { return i < s.size() ? static_cast<unsigned char>(s[i]) : 0u; };
  const auto cont = [&](std::size_t i) { return (byte(i) & 0xC0u) == 0x80u; };
  std::size_t i = 0;
  while (i < s.size()) {
    const unsigned b = byte(i);
    std::size_t n = 0;  // length of a well-formed sequence starting at i, 0 if none
    if (b < 0x80) {
      n = (b >= 0x20 || b == '\t' || b == '\n' || b == '\r') ? 1 : 0;
    } else if (b >= 0xC2 && b <= 0xDF) {
      n = cont(i + 1) ? 2 : 0;
    } else if (b >= 0xE0 && b <= 0xEF) {
      const unsigned b1 = byte(i + 1);
      const bool ok1 = b == 0xE0 ? (b1 >= 0xA0 && b1 <= 0xBF) : b == 0xED ? (b1 >= 0x80 && b1 <= 0x9F) : cont(i + 1);
      const bool nonchar = b == 0xEF && b1 == 0xBF && (byte(i + 2) == 0xBE || byte(i + 2) == 0xBF);  // U+FFFE/F
      n = ok1 && cont(i + 2) && !nonchar ? 3 : 0;
    } else if (b >= 0xF0 && b <= 0xF4) {
      const unsigned b1 = byte(i + 1);
      const bool ok1 = b == 0xF0 ? (b1 >= 0x90 && b1 <= 0xBF) : b == 0xF4 ? (b1 >= 0x80 && b1 <= 0x8F) : cont(i + 1);
      n = ok1 && cont(i + 2) && cont(i + 3) ? 4 : 0;
    }
    if (n == 0) {
      out += kReplacement;
      ++i;
    } else {
      out.append(s.substr(i, n));
      i += n;
    }
  }
  return out;
}

// At most the last `limit` bytes of a child's output, saying how much was left out.
std::string tail(const std::string& s, std::size_t limit = 64 * 1024) {
  if (s.size() <= limit) return s;
  return fmt::format("[... the first {} bytes left out ...]\n{}", s.size() - limit, s.substr(s.size() - limit));
}

std::string seconds(double s) {
  return fmt::format("{:.3f}", s);
}

}  // namespace

std::string format_result(const CaseResult& r, std::size_t name_width) {
  const std::string sim = r.sim_time ? fmt::format("{:8.2f} s", *r.sim_time) : fmt::format("{:>8}  ", "-");
  const std::string placed = r.placed ? std::to_string(*r.placed) : std::string("-");
  return fmt::format("{:<5}  {:<{}}  sim {}  wall {:6.1f} s  placed {}{}", upper(to_string(r.verdict)), r.test.name,
                     name_width, sim, r.end.wall_time, placed, r.message.empty() ? std::string() : "  " + r.message);
}

std::string format_totals(const std::vector<CaseResult>& results) {
  std::map<Verdict, std::size_t> n;
  for (const CaseResult& r : results) ++n[r.verdict];
  const std::size_t passed = n[Verdict::kPass];
  std::string s = fmt::format("{} passed, {} failed", passed, results.size() - passed);
  std::string other;
  const auto add = [&](Verdict v, const char* word) {
    if (n[v] > 0) other += fmt::format("{}{} {}", other.empty() ? "" : ", ", n[v], word);
  };
  add(Verdict::kCrash, "crashed");
  add(Verdict::kHang, "hung");
  add(Verdict::kError, "refused");
  return other.empty() ? s : s + " (" + other + ")";
}

std::string format_junit(const std::vector<CaseResult>& results, double wall_time) {
  std::size_t failures = 0, errors = 0;
  for (const CaseResult& r : results) {
    if (r.verdict == Verdict::kFail) ++failures;
    if (r.verdict == Verdict::kError || r.verdict == Verdict::kCrash || r.verdict == Verdict::kHang) ++errors;
  }
  xml::Writer w(2);
  w.declaration("xml version=\"1.0\" encoding=\"UTF-8\"");
  const xml::Attributes counts = {{"tests", std::to_string(results.size())},
                                  {"failures", std::to_string(failures)},
                                  {"errors", std::to_string(errors)}};
  xml::Attributes suites = {{"name", "twin test"}};
  suites.insert(suites.end(), counts.begin(), counts.end());
  suites.emplace_back("time", seconds(wall_time));
  w.open("testsuites", suites);
  xml::Attributes suite = {{"name", "twin test"}};
  suite.insert(suite.end(), counts.begin(), counts.end());
  suite.emplace_back("skipped", "0");
  suite.emplace_back("time", seconds(wall_time));
  w.open("testsuite", suite);
  for (const CaseResult& r : results) {
    std::string folder = r.test.scenario.parent_path().filename().string();
    if (folder.empty()) folder = ".";
    w.open("testcase", {{"name", xml_safe(r.test.name)},
                        {"classname", xml_safe(folder)},
                        {"file", xml_safe(r.test.scenario.string())},
                        {"time", seconds(r.end.wall_time)}});
    if (!r.passed()) {
      std::string body;
      for (const std::string& f : r.failures) body += f + "\n";
      if (r.kept) body += fmt::format("outputs in {}\n", r.test.dir.string());
      if (!r.video.empty()) body += fmt::format("video in {}\n", r.video.string());
      if (!r.video_note.empty()) body += fmt::format("video: {}\n", r.video_note);
      w.open(r.verdict == Verdict::kFail ? "failure" : "error",
             {{"message", xml_safe(r.message)}, {"type", to_string(r.verdict)}});
      w.text(xml_safe(body));
      w.close();
    }
    if (!r.output.empty()) w.text_element("system-out", xml_safe(tail(r.output)));
    if (!r.errors.empty()) w.text_element("system-err", xml_safe(tail(r.errors)));
    w.close();
  }
  w.close();
  w.close();
  return w.str();
}

}  // namespace cellwright::cell
