// Video of a run (video.hpp): the `ffmpeg` program encodes, a thread of our own renders.
#include "cellwright/twin/video.hpp"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fmt/format.h>

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string_view>
#include <utility>

#include "cellwright/common/error.hpp"
#include "cellwright/twin/render.hpp"
#include "cellwright/twin/sim/world.hpp"

extern char** environ;

namespace cellwright::twin {

namespace {

constexpr int kMaxSide = 4096;
constexpr std::size_t kQueue = 4;  // frames the recording thread may be behind the simulation

// Writes all of `size` bytes to `fd`; false with errno set when the reader has gone (EPIPE) or writing fails. SIGPIPE
// is blocked in this thread while writing (and a pending one taken), so a dead encoder is an error, never the end
// of the process.
bool write_all(int fd, const char* data, std::size_t size) {
  sigset_t pipe_set, old;
  sigemptyset(&pipe_set);
  sigaddset(&pipe_set, SIGPIPE);
  pthread_sigmask(SIG_BLOCK, &pipe_set, &old);
  bool ok = true;
  int error = 0;
  while (size > 0) {
    const ssize_t n = ::write(fd, data, size);
    if (n < 0) {
      if (errno == EINTR) continue;
      ok = false;
      error = errno;
      break;
    }
    data += n;
    size -= static_cast<std::size_t>(n);
  }
  if (!ok && error == EPIPE && sigismember(&old, SIGPIPE) == 0) {
    const timespec zero{0, 0};
    sigtimedwait(&pipe_set, nullptr, &zero);  // the SIGPIPE that write raised, so that it is not delivered later
  }
  pthread_sigmask(SIG_SETMASK, &old, nullptr);
  errno = error;
  return ok;
}

}  // namespace

struct VideoWriter::Impl {
  pid_t pid = -1;
  int input = -1;              // the write end of ffmpeg's standard input
  std::filesystem::path log;   // ffmpeg's standard error, for the message when it fails
  int width = 0, height = 0;

  // ffmpeg's last lines of error output (it is quiet but for errors).
  std::string errors() const {
    std::ifstream in(log);
    std::stringstream text;
    text << in.rdbuf();
    std::string s = text.str();
    while (!s.empty() && (s.back() == '\n' || s.back() == '\r')) s.pop_back();
    if (s.size() > 600) s = "..." + s.substr(s.size() - 600);
    return s.empty() ? std::string("no message") : s;
  }
  // Closes ffmpeg's input and waits for it; its exit status (-1 if it did not exit normally).
  int wait() {
    if (input >= 0) ::close(input);
    input = -1;
    int status = 0;
    if (pid > 0) {
      while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
      }
    }
    pid = -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }
  ~Impl() {
    wait();
    std::error_code ec;
    if (!log.empty()) std::filesystem::remove(log, ec);
  }
};

VideoWriter::VideoWriter() = default;

VideoWriter::~VideoWriter() {
  try {
    close();
  } catch (const std::exception&) {
    release();  // a destructor reports nothing; close() is where errors are seen
  }
}

bool VideoWriter::is_open() const { return impl_ != nullptr; }

void VideoWriter::release() { impl_.reset(); }

void VideoWriter::check_format(const SourceLocation& where, int width, int height, int fps) {
  if (width < 2 || height < 2 || width > kMaxSide || height > kMaxSide || width % 2 != 0 || height % 2 != 0) {
    throw InputError(where, fmt::format("video size {}x{}: width and height must be even (yuv420p) and within "
                                        "2..{} pixels",
                                        width, height, kMaxSide));
  }
  if (fps < 1 || fps > 120) {
    throw InputError(where, fmt::format("video rate {} frames per second is not within 1..120", fps));
  }
}

void VideoWriter::check_encoder(const SourceLocation& where) {
  const char* path = std::getenv("PATH");
  std::string_view dirs = path != nullptr ? path : "";
  for (;;) {
    const std::size_t colon = dirs.find(':');
    const std::string_view dir = dirs.substr(0, colon);
    const std::filesystem::path candidate = std::filesystem::path(dir.empty() ? "." : std::string(dir)) / "ffmpeg";
    if (::access(candidate.c_str(), X_OK) == 0 && !std::filesystem::is_directory(candidate)) return;
    if (colon == std::string_view::npos) break;
    dirs.remove_prefix(colon + 1);
  }
  throw InputError(where, "cannot record videos: the ffmpeg program is not on PATH; it is Debian's package ffmpeg");
}

void VideoWriter::open(const std::filesystem::path& path, int width, int height, int fps) {
  close();
  const SourceLocation where{path.string(), 0, 0};
  if (path.extension() != ".mp4") {
    throw InputError(where, fmt::format("a video is written as MP4 (H.264): the file name must end in .mp4, not '{}'",
                                        path.extension().string()));
  }
  check_format(where, width, height, fps);
  const std::filesystem::path dir = path.has_parent_path() ? path.parent_path() : std::filesystem::path(".");
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec)) {
    throw InputError(where, fmt::format("cannot write the video: directory '{}' does not exist", dir.string()));
  }
  // The file is made here, so that one that cannot be written is refused now, before any run starts.
  if (const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666); fd < 0) {
    throw InputError(where, fmt::format("cannot write the video: {}", std::strerror(errno)));
  } else {
    ::close(fd);
  }

  auto impl = std::make_unique<Impl>();
  impl->width = width;
  impl->height = height;
  std::string log_name = (std::filesystem::temp_directory_path() / "cellwright-ffmpeg-XXXXXX").string();
  const int log_fd = ::mkostemp(log_name.data(), O_CLOEXEC);
  if (log_fd < 0) throw std::runtime_error(fmt::format("cannot make a temporary file: {}", std::strerror(errno)));
  impl->log = log_name;
  int pipe_fds[2];
  if (::pipe2(pipe_fds, O_CLOEXEC) != 0) {
    ::close(log_fd);
    throw std::runtime_error(fmt::format("cannot make a pipe: {}", std::strerror(errno)));
  }
  impl->input = pipe_fds[1];

  // Raw BGR frames in on standard input, H.264 / yuv420p in an MP4 with its index first out (docs/scenarios.md).
  const std::string size = fmt::format("{}x{}", width, height), rate = std::to_string(fps),
                    gop = std::to_string(2 * fps), target = "file:" + path.string();
  std::vector<std::string> argv_text = {"ffmpeg", "-hide_banner", "-loglevel", "error", "-y",
                                        "-f", "rawvideo", "-pix_fmt", "bgr24", "-video_size", size,
                                        "-framerate", rate, "-i", "pipe:0", "-an",
                                        "-c:v", "libx264", "-preset", "veryfast", "-crf", "23",
                                        "-pix_fmt", "yuv420p", "-g", gop,  // a key frame every 2 s: quick seeking
                                        "-movflags", "+faststart", "-f", "mp4", target};
  std::vector<char*> argv;
  for (std::string& a : argv_text) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, pipe_fds[0], STDIN_FILENO);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_adddup2(&actions, log_fd, STDERR_FILENO);
  posix_spawnattr_t attributes;
  posix_spawnattr_init(&attributes);
  sigset_t none, pipe_default;
  sigemptyset(&none);
  sigemptyset(&pipe_default);
  sigaddset(&pipe_default, SIGPIPE);
  // ffmpeg with no signal blocked (a run blocks SIGINT and SIGTERM in its threads) and SIGPIPE as by default, in a
  // process group of its own: a Ctrl-C at the terminal goes to the foreground group, and it is twin's to stop the run
  // and then close the video, not ffmpeg's to die mid-file. Should twin die, ffmpeg sees the end of its input.
  posix_spawnattr_setsigmask(&attributes, &none);
  posix_spawnattr_setsigdefault(&attributes, &pipe_default);
  posix_spawnattr_setpgroup(&attributes, 0);
  posix_spawnattr_setflags(&attributes, POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETSIGDEF | POSIX_SPAWN_SETPGROUP);
  const int rc = posix_spawnp(&impl->pid, "ffmpeg", &actions, &attributes, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  posix_spawnattr_destroy(&attributes);
  ::close(pipe_fds[0]);
  ::close(log_fd);
  if (rc != 0) {
    impl->pid = -1;
    std::filesystem::remove(path, ec);
    throw InputError(where, fmt::format("cannot record the video: the ffmpeg program could not be started ({}); "
                                        "it is Debian's package ffmpeg",
                                        std::strerror(rc)));
  }
  impl_ = std::move(impl);
  path_ = path;
  frames_ = 0;
}

void VideoWriter::add(const cv::Mat& image) {
  CW_CHECK(impl_ != nullptr, "VideoWriter::add on a closed writer");
  Impl& v = *impl_;
  CW_CHECK(image.type() == CV_8UC3 && image.cols == v.width && image.rows == v.height,
           "a video frame must be {}x{} BGR, got {}x{} of type {}", v.width, v.height, image.cols, image.rows,
           image.type());
  const cv::Mat packed = image.isContinuous() ? image : image.clone();
  if (!write_all(v.input, reinterpret_cast<const char*>(packed.data), packed.total() * packed.elemSize())) {
    const std::string why = std::strerror(errno);
    v.wait();
    const std::string message = fmt::format("cannot encode the video ({}): ffmpeg: {}", why, v.errors());
    release();
    throw InputError({path_.string(), 0, 0}, message);
  }
  ++frames_;
}

void VideoWriter::close() {
  if (impl_ == nullptr) return;
  const int status = impl_->wait();  // end of input: ffmpeg flushes, writes the index first and exits
  if (status != 0) {
    const std::string message =
        fmt::format("cannot write the video: ffmpeg exited with status {}: {}", status, impl_->errors());
    release();
    throw InputError({path_.string(), 0, 0}, message);
  }
  release();
}

std::vector<std::string> device_lines(const sim::DeviceStates& devices) {
  std::vector<std::string> out;
  for (const sim::MachineDevice& m : devices.machines) {
    std::string line = fmt::format("{}: {}", m.name, sim::to_string(m.state));
    if (m.state != sim::MachineState::idle && !m.part.empty()) line += " " + m.part;
    if (m.busy()) line += fmt::format(" ({:.1f} s left)", std::chrono::duration<double>(m.busy_left).count());
    if (m.done()) line += " (to unload)";
    out.push_back(std::move(line));
  }
  for (const sim::ConveyorDevice& c : devices.conveyors) {
    std::string line =
        fmt::format("{}: {}", c.name, c.running ? "running" : c.run ? "held (accumulating)" : "stopped");
    if (c.stop_eye) line += ", stop eye on";
    if (c.drop_eye) line += ", drop eye on";
    out.push_back(std::move(line));
  }
  return out;
}

void draw_overlay(cv::Mat& image, const Overlay& overlay) {
  CW_CHECK(image.type() == CV_8UC3, "draw_overlay needs an 8-bit, 3-channel image");
  const int font = cv::FONT_HERSHEY_SIMPLEX;
  // Text scaled to the picture: 0.5 at 600 pixels high.
  const double scale = std::max(0.35, image.rows / 1200.0);
  const int thickness = 1;
  int baseline = 0;
  const int line_height = cv::getTextSize("Ag", font, scale, thickness, &baseline).height + baseline + 6;
  auto darken = [&image](cv::Rect band) {
    band &= cv::Rect(0, 0, image.cols, image.rows);
    if (band.area() == 0) return;
    cv::Mat roi = image(band);
    roi.convertTo(roi, -1, 0.35);  // the picture shows through, the text stands out
  };
  if (!overlay.lines.empty()) {
    int width = 0;
    for (const std::string& line : overlay.lines) {
      width = std::max(width, cv::getTextSize(line, font, scale, thickness, &baseline).width);
    }
    darken(cv::Rect(0, 0, width + 16, line_height * static_cast<int>(overlay.lines.size()) + 8));
    int y = line_height;
    for (const std::string& line : overlay.lines) {
      cv::putText(image, line, cv::Point(8, y), font, scale, cv::Scalar(255, 255, 255), thickness, cv::LINE_AA);
      y += line_height;
    }
  }
  if (!overlay.verdict.empty()) {
    const double big = 1.5 * scale;
    const cv::Size size = cv::getTextSize(overlay.verdict, font, big, 2, &baseline);
    const int band = size.height + baseline + 20;
    darken(cv::Rect(0, image.rows - band, image.cols, band));
    const cv::Scalar colour = overlay.verdict_ok ? cv::Scalar(80, 220, 80) : cv::Scalar(60, 60, 240);  // BGR
    cv::putText(image, overlay.verdict, cv::Point(std::max(8, (image.cols - size.width) / 2), image.rows - baseline - 10),
                font, big, colour, 2, cv::LINE_AA);
  }
}

VideoRecorder::VideoRecorder(const mjModel* model, VideoOptions options) : model_(model), options_(std::move(options)) {
  CW_CHECK(model_ != nullptr, "VideoRecorder needs a model");
  writer_.open(options_.path, options_.width, options_.height, options_.fps);
  thread_ = std::thread([this] { loop(); });
}

VideoRecorder::~VideoRecorder() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
    Frame end;
    end.last = true;
    end.repeat = 0;
    queue_.push_back(std::move(end));
  }
  changed_.notify_all();
  if (thread_.joinable()) thread_.join();
}

runtime::SimDuration VideoRecorder::frame_period() const {
  return std::chrono::duration_cast<runtime::SimDuration>(std::chrono::duration<double>(1.0 / options_.fps));
}

VideoRecorder::Frame VideoRecorder::capture(const mjData* data, runtime::SimDuration t) const {
  Frame f;
  f.time = t;
  f.qpos.assign(data->qpos, data->qpos + model_->nq);
  f.mocap_pos.assign(data->mocap_pos, data->mocap_pos + 3 * model_->nmocap);
  f.mocap_quat.assign(data->mocap_quat, data->mocap_quat + 4 * model_->nmocap);
  f.userdata.assign(data->userdata, data->userdata + model_->nuserdata);  // colours changed by the run
  return f;
}

void VideoRecorder::push(Frame frame) {
  std::unique_lock lock(mutex_);
  changed_.wait(lock, [this] { return stop_ || queue_.size() < kQueue; });
  if (stop_) return;
  queue_.push_back(std::move(frame));
  changed_.notify_all();
}

namespace {

std::string time_line(runtime::SimDuration t) {
  return fmt::format("t = {:.2f} s", std::chrono::duration<double>(t).count());
}

}  // namespace

void VideoRecorder::record(const mjData* data, runtime::SimDuration t, std::vector<std::string> robot_lines) {
  Frame f = capture(data, t);
  last_lines_ = std::move(robot_lines);
  f.overlay.lines.push_back(time_line(t));
  f.overlay.lines.insert(f.overlay.lines.end(), last_lines_.begin(), last_lines_.end());
  push(std::move(f));
}

void VideoRecorder::finish(const mjData* data, runtime::SimDuration t, const std::string& verdict, bool ok) {
  Frame f = capture(data, t);
  f.overlay.lines.push_back(time_line(t));
  f.overlay.lines.insert(f.overlay.lines.end(), last_lines_.begin(), last_lines_.end());
  f.overlay.verdict = verdict;
  f.overlay.verdict_ok = ok;
  f.repeat = std::max(1, static_cast<int>(options_.hold * options_.fps + 0.5));
  f.last = true;
  push(std::move(f));
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  changed_.notify_all();
  if (thread_.joinable()) thread_.join();
  std::exception_ptr error;
  {
    std::lock_guard lock(mutex_);
    error = error_;
  }
  if (error) {
    try {
      std::rethrow_exception(error);
    } catch (const InputError&) {
      throw;
    } catch (const std::exception& e) {
      throw InputError({options_.path.string(), 0, 0}, fmt::format("the video could not be recorded: {}", e.what()));
    }
  }
  writer_.close();
}

std::int64_t VideoRecorder::frames() const {
  std::lock_guard lock(mutex_);
  return encoded_;
}

void VideoRecorder::loop() {
  std::unique_ptr<mjData, void (*)(mjData*)> data(mj_makeData(model_), mj_deleteData);
  std::optional<Renderer> renderer;
  std::optional<mjvCamera> camera;
  try {
    if (data == nullptr) throw std::runtime_error("MuJoCo could not make data for the video");
    renderer.emplace(model_, options_.width, options_.height);
    for (;;) {
      Frame f;
      {
        std::unique_lock lock(mutex_);
        changed_.wait(lock, [this] { return !queue_.empty(); });
        f = std::move(queue_.front());
        queue_.pop_front();
      }
      changed_.notify_all();
      if (f.repeat > 0) {
        // The frame's state: positions are all a picture needs (kinematics places the bodies, cameras and lights).
        mjData* d = data.get();
        std::copy(f.qpos.begin(), f.qpos.end(), d->qpos);
        std::copy(f.mocap_pos.begin(), f.mocap_pos.end(), d->mocap_pos);
        std::copy(f.mocap_quat.begin(), f.mocap_quat.end(), d->mocap_quat);
        std::copy(f.userdata.begin(), f.userdata.end(), d->userdata);
        d->time = std::chrono::duration<double>(f.time).count();
        mj_kinematics(model_, d);
        mj_comPos(model_, d);
        mj_camlight(model_, d);
        if (!camera) camera = renderer->overview_camera(d, options_.width, options_.height);
        cv::Mat image = renderer->render(d, *camera, options_.width, options_.height);
        draw_overlay(image, f.overlay);
        for (int i = 0; i < f.repeat; ++i) writer_.add(image);
        std::lock_guard lock(mutex_);
        encoded_ = writer_.frames();
      }
      if (f.last) break;
    }
  } catch (...) {
    std::lock_guard lock(mutex_);
    error_ = std::current_exception();
    stop_ = true;
    changed_.notify_all();
  }
  renderer.reset();  // on this thread, which made its OpenGL context
}

}  // namespace cellwright::twin
