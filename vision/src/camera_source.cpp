#include "cellwright/vision/camera_source.hpp"

#include <glob.h>

#include <fmt/format.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>

#include "cellwright/common/files.hpp"
#include "cellwright/vision/camera_model.hpp"
#include "cellwright/vision/cell_detector.hpp"

namespace cellwright::vision {

namespace {

constexpr const char* kForm = "NAME=v4l2:/dev/videoN or NAME=file:VIDEO_OR_GLOB[,fps=N]";

double seconds(runtime::SimDuration t) { return std::chrono::duration<double>(t).count(); }

}  // namespace

bool CameraText::images() const { return path.find_first_of("*?[") != std::string::npos; }

CameraText parse_camera_text(const std::string& text, const SourceLocation& where) {
  CameraText c;
  c.text = text;
  const auto fail = [&](const std::string& problem) {
    throw InputError(where, fmt::format("'{}': {} (expected {})", text, problem, kForm));
  };
  const std::size_t eq = text.find('=');
  if (eq == std::string::npos) fail("no '=' between the camera's name and its source");
  if (eq == 0) fail("no camera name before '='");
  c.camera = text.substr(0, eq);
  std::string source = text.substr(eq + 1);
  const std::size_t colon = source.find(':');
  if (colon == std::string::npos) fail("no kind of source (v4l2: or file:)");
  const std::string kind = source.substr(0, colon);
  std::string rest = source.substr(colon + 1);
  if (kind == "v4l2") {
    c.kind = CameraText::Kind::kDevice;
  } else if (kind == "file") {
    c.kind = CameraText::Kind::kFile;
  } else {
    fail(fmt::format("unknown kind of source '{}'", kind));
  }
  if (const std::size_t comma = rest.rfind(",fps="); comma != std::string::npos) {
    if (c.kind == CameraText::Kind::kDevice) fail("fps= is for a recording; a device has its own rate");
    const std::string number = rest.substr(comma + 5);
    double fps = 0;
    const auto [end, ec] = std::from_chars(number.data(), number.data() + number.size(), fps);
    if (ec != std::errc() || end != number.data() + number.size() || !(fps > 0 && fps <= 1000)) {
      fail(fmt::format("fps must be a number of frames per second, 0 < fps <= 1000, got '{}'", number));
    }
    c.fps = fps;
    rest.resize(comma);
  }
  if (rest.empty()) fail(c.kind == CameraText::Kind::kDevice ? "no device path" : "no file");
  c.path = rest;
  return c;
}

Intrinsics read_intrinsics(const std::filesystem::path& file) {
  if (const std::string problem = not_a_file(file); !problem.empty()) {
    throw InputError({file.string(), 0, 0}, fmt::format("the intrinsics file {}", problem));
  }
  cv::FileStorage fs;
  try {
    fs.open(file.string(), cv::FileStorage::READ | cv::FileStorage::FORMAT_AUTO);
  } catch (const cv::Exception& e) {
    throw InputError({file.string(), 0, 0},
                     fmt::format("not a file OpenCV's FileStorage reads (YAML or XML of its calibration tools): {}",
                                 e.err));
  }
  if (!fs.isOpened()) throw InputError({file.string(), 0, 0}, "cannot be opened by OpenCV's FileStorage");
  const auto need = [&](const char* key) {
    const cv::FileNode n = fs[key];
    if (n.empty() || n.isNone()) {
      throw InputError({file.string(), 0, 0},
                       fmt::format("the intrinsics have no '{}' (OpenCV's calibration output has camera_matrix, "
                                   "distortion_coefficients, image_width and image_height)",
                                   key));
    }
    return n;
  };
  Intrinsics in;
  in.source = file;
  cv::Mat k, d;
  try {
    need("camera_matrix") >> k;
    need("distortion_coefficients") >> d;
    in.size = {static_cast<int>(need("image_width")), static_cast<int>(need("image_height"))};
  } catch (const cv::Exception& e) {
    throw InputError({file.string(), 0, 0}, fmt::format("a value of the wrong type: {}", e.err));
  }
  if (k.rows != 3 || k.cols != 3) {
    throw InputError({file.string(), 0, 0}, fmt::format("camera_matrix must be 3 x 3, got {} x {}", k.rows, k.cols));
  }
  k.convertTo(k, CV_64F);
  for (int r = 0; r < 3; ++r) {
    for (int col = 0; col < 3; ++col) in.camera_matrix(r, col) = k.at<double>(r, col);
  }
  const int n = static_cast<int>(d.total());
  if (n != 4 && n != 5 && n != 8 && n != 12 && n != 14) {
    throw InputError({file.string(), 0, 0},
                     fmt::format("distortion_coefficients must have 4, 5, 8, 12 or 14 numbers, got {}", n));
  }
  d.convertTo(d, CV_64F);
  in.distortion.assign(d.ptr<double>(), d.ptr<double>() + n);
  if (in.size.width < 16 || in.size.height < 16 || in.size.width > 8192 || in.size.height > 8192) {
    throw InputError({file.string(), 0, 0},
                     fmt::format("image_width and image_height must be 16..8192 pixels, got {} x {}", in.size.width,
                                 in.size.height));
  }
  const cv::Matx33d& m = in.camera_matrix;
  if (!(m(0, 0) > 0 && m(1, 1) > 0 && m(2, 2) == 1 && m(1, 0) == 0 && m(2, 0) == 0 && m(2, 1) == 0)) {
    throw InputError({file.string(), 0, 0},
                     "camera_matrix is not a camera's (fx > 0, fy > 0, the last row 0 0 1, zeros below the diagonal)");
  }
  for (double v : in.distortion) {
    if (!std::isfinite(v)) throw InputError({file.string(), 0, 0}, "distortion_coefficients has a non-finite number");
  }
  return in;
}

Undistortion::Undistortion(const models::CameraSpec& camera, const Intrinsics* intrinsics)
    : input_(camera.width, camera.height), output_(camera.width, camera.height) {
  if (intrinsics == nullptr) return;
  input_ = intrinsics->size;
  const Eigen::Matrix3d ideal = CameraModel(camera).intrinsics();
  cv::Matx33d target;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) target(r, c) = ideal(r, c);
  }
  cv::initUndistortRectifyMap(intrinsics->camera_matrix, intrinsics->distortion, cv::noArray(), target, output_,
                              CV_16SC2, map1_, map2_);
}

cv::Mat Undistortion::apply(const cv::Mat& raw) const {
  CW_CHECK(raw.cols == input_.width && raw.rows == input_.height, "a {} x {} frame undistorted as {} x {}", raw.cols,
           raw.rows, input_.width, input_.height);
  if (map1_.empty()) return raw;
  cv::Mat out;
  cv::remap(raw, out, map1_, map2_, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0, 0, 0));
  return out;
}

cv::Mat as_bgr(const cv::Mat& frame) {
  CW_CHECK(frame.depth() == CV_8U, "a camera frame of depth {} (8-bit expected)", frame.depth());
  if (frame.channels() == 3) return frame;
  cv::Mat out;
  cv::cvtColor(frame, out, frame.channels() == 1 ? cv::COLOR_GRAY2BGR : cv::COLOR_BGRA2BGR);
  return out;
}

CameraSource::CameraSource(const CameraText& text, const models::CameraSpec& camera)
    : text_(text), camera_(camera.name) {
  std::optional<Intrinsics> intrinsics;
  if (!camera.intrinsics.empty()) intrinsics = read_intrinsics(camera.intrinsics);
  undistort_ = std::make_unique<Undistortion>(camera, intrinsics ? &*intrinsics : nullptr);
  std::string why;
  std::optional<cv::Mat> first;
  if (text_.kind == CameraText::Kind::kDevice) {
    if (const std::string problem = not_a_file(text_.path); problem == "no such file") {
      throw InputError({text_.path, 0, 0}, fmt::format("the camera device of '{}': no such device", text_.text));
    }
    grabber_ = open_grabber(text_.path, true);
    cv::Mat f;
    if (grabber_->read(f)) first = as_bgr(f);
    why = "the device gave no frame";
  } else if (text_.images()) {
    glob_t g{};
    const int rc = ::glob(text_.path.c_str(), GLOB_ERR, nullptr, &g);
    for (std::size_t i = 0; rc == 0 && i < g.gl_pathc; ++i) files_.emplace_back(g.gl_pathv[i]);
    globfree(&g);
    if (files_.empty()) {
      throw InputError({text_.path, 0, 0}, fmt::format("no file matches the camera's glob (from '{}')", text_.text));
    }
    std::sort(files_.begin(), files_.end());
    if (!text_.fps) {
      throw InputError({"--camera", 0, 0},
                       fmt::format("'{}': an image sequence needs its rate: add ,fps=N (frames per second)", text_.text));
    }
    fps_ = *text_.fps;
    first = recorded(0, &why);
  } else {
    if (const std::string problem = not_a_file(text_.path); !problem.empty()) {
      throw InputError({text_.path, 0, 0}, fmt::format("the camera's video file (from '{}') {}", text_.text, problem));
    }
    grabber_ = open_grabber(text_.path, false);
    fps_ = text_.fps.value_or(grabber_->fps());
    if (!(fps_ > 0 && fps_ <= 1000)) {
      throw InputError({text_.path, 0, 0},
                       fmt::format("the video does not say its frame rate (got {}): add ,fps=N to '{}'", fps_,
                                   text_.text));
    }
    first = recorded(0, &why);
  }
  if (!first) throw InputError({text_.path, 0, 0}, fmt::format("no first frame from '{}': {}", text_.text, why));
  const cv::Size want = undistort_->input_size();
  if (first->cols != want.width || first->rows != want.height) {
    throw InputError({text_.path, 0, 0},
                     fmt::format("its frames are {} x {} pixels, and camera '{}' takes {} x {} ({})", first->cols,
                                 first->rows, camera_, want.width, want.height,
                                 intrinsics ? fmt::format("the size of its intrinsics {}", intrinsics->source.string())
                                            : std::string("its resolution in the cell description")));
  }
  first_ = undistort_->apply(*first);
  if (live()) {
    newest_ = *first;
    newest_seq_ = 1;
    reader_ = std::thread([this] { read_device(); });
  }
}

CameraSource::~CameraSource() {
  stop_ = true;
  if (reader_.joinable()) reader_.join();
}

void CameraSource::read_device() {
  while (!stop_) {
    cv::Mat f;
    const bool ok = grabber_->read(f);
    std::lock_guard lock(mutex_);
    if (!ok) {
      device_problem_ = fmt::format("the camera {} stopped delivering frames", text_.path);
      changed_.notify_all();
      return;
    }
    newest_ = as_bgr(f);
    ++newest_seq_;
    changed_.notify_all();
  }
}

std::optional<cv::Mat> CameraSource::live_frame(std::string* why) {
  std::unique_lock lock(mutex_);
  changed_.wait_for(lock, kDeviceWait, [&] { return newest_seq_ != delivered_seq_ || !device_problem_.empty(); });
  if (newest_seq_ != delivered_seq_) {
    delivered_seq_ = newest_seq_;
    return newest_.clone();
  }
  *why = !device_problem_.empty()
             ? device_problem_
             : fmt::format("no frame from the camera {} for {} ms", text_.path, kDeviceWait.count());
  return std::nullopt;
}

std::optional<cv::Mat> CameraSource::recorded(std::int64_t index, std::string* why) {
  const auto past_end = [&](std::int64_t frames) {
    *why = fmt::format("the recording {} ended after {} frames ({:.3f} s at {:g} fps); frame {} is not in it",
                       text_.path, frames, static_cast<double>(frames) / fps_, fps_, index);
    return std::nullopt;
  };
  if (!files_.empty()) {
    if (index >= static_cast<std::int64_t>(files_.size())) return past_end(static_cast<std::int64_t>(files_.size()));
    try {
      return as_bgr(read_image(files_[static_cast<std::size_t>(index)]));
    } catch (const InputError& e) {
      *why = e.what();
      return std::nullopt;
    }
  }
  if (!ended_.empty()) {
    *why = ended_;
    return std::nullopt;
  }
  if (index < read_ - 1) {
    *why = fmt::format("frame {} of {} asked for after frame {}", index, text_.path, read_ - 1);
    return std::nullopt;
  }
  while (read_ <= index) {
    cv::Mat f;
    if (!grabber_->read(f)) {
      past_end(read_);
      ended_ = *why;
      return std::nullopt;
    }
    last_ = as_bgr(f);
    ++read_;
  }
  return last_;
}

std::optional<runtime::Image> CameraSource::deliver(const cv::Mat& raw, std::string* why) const {
  const cv::Size want = undistort_->input_size();
  if (raw.cols != want.width || raw.rows != want.height) {
    *why = fmt::format("a frame of {} x {} pixels from {}, not {} x {}", raw.cols, raw.rows, text_.path, want.width,
                       want.height);
    return std::nullopt;
  }
  return to_image(undistort_->apply(raw));
}

std::optional<runtime::Image> CameraSource::capture(runtime::SimDuration t, std::string* why) {
  std::string problem;
  std::optional<cv::Mat> raw =
      live() ? live_frame(&problem) : recorded(std::llround(seconds(t) * fps_), &problem);
  std::optional<runtime::Image> image;
  if (raw) image = deliver(*raw, &problem);
  if (!image && why != nullptr) *why = problem;
  return image;
}

}  // namespace cellwright::vision
