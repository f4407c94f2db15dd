// A real camera as the runtime's FrameSource (issue 26; runtime/frame_source.hpp): the image-processing thread takes
// its frames from a V4L2 device or from a recording (a video file, or image files) instead of the twin's renderer.
//
//  - `--camera NAME=v4l2:/dev/videoN` (twin run): a live camera. A thread of its own reads it as fast as it delivers
//    and keeps the newest frame; capture() hands over a frame newer than the last one it gave, waiting at most
//    kDeviceWait for one. A device that stops delivering (unplugged, gone) is a frame that did not come: the
//    runtime's frame-lost symptom, never a hang. A live camera paces nothing: runs with one are real-time.
//  - `--camera NAME=file:VIDEO` or `file:GLOB,fps=N` (image files matching GLOB, taken in sorted order, at N frames a
//    second): a recording. Frame i is the picture of time i / fps (a video's rate is the file's unless `,fps=N`
//    says otherwise); capture(t) gives frame round(t * fps), whatever the wall clock, so that a lock-step run of a
//    recording is repeatable to the byte. A recording that ends before the run does gives nothing from then on,
//    with the reason (the frame-lost symptom).
// Every frame is brought to the cell camera's pinhole before detection (Undistortion below): with the camera's
// `intrinsics` file (OpenCV's calibration output), undistorted and resampled into the pinhole of the cell
// description's `resolution` and `fovy`; without one, the frames must already be that pinhole's (the twin's own
// recordings are) and pass unchanged.
//
// Threads: a CameraSource is built on the main thread; capture() then runs on the simulation thread only. The live
// camera's reader thread is its own, joined by the destructor.
#pragma once

#include <opencv2/core.hpp>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "cellwright/common/error.hpp"
#include "cellwright/models/cell.hpp"
#include "cellwright/runtime/frame_source.hpp"
#include "cellwright/vision/frame_grabber.hpp"

namespace cellwright::vision {

// `NAME=v4l2:DEVICE` or `NAME=file:VIDEO_OR_GLOB[,fps=N]`, as given to --camera.
struct CameraText {
  enum class Kind { kDevice, kFile };
  std::string camera;         // the cell camera it stands for
  Kind kind = Kind::kFile;
  std::string path;           // the device, the video file or the glob
  std::optional<double> fps;  // `,fps=N` (file only)
  std::string text;           // as given

  // Whether `path` is a glob of image files (it has *, ? or [), not a video file.
  bool images() const;
};

// Parses a --camera text; InputError at `where` naming the text and what is wrong (no NAME=, an unknown kind, an
// empty path, a bad or non-positive fps, fps on a device). The camera's name is not checked here.
CameraText parse_camera_text(const std::string& text, const SourceLocation& where);

// A camera's intrinsics and lens distortion, as OpenCV's calibration tools (calibrateCamera and the tutorial's
// camera_calibration program) write them with cv::FileStorage: `camera_matrix` (3 x 3), `distortion_coefficients`
// (4, 5, 8, 12 or 14 numbers, OpenCV's order k1 k2 p1 p2 [k3 ...]), `image_width`, `image_height`.
struct Intrinsics {
  cv::Matx33d camera_matrix;
  std::vector<double> distortion;
  cv::Size size;
  std::filesystem::path source;
};

// Reads an intrinsics file. InputError naming the file and the missing or bad key.
Intrinsics read_intrinsics(const std::filesystem::path& file);

// From the real camera's picture to the cell camera's pinhole (camera_model.hpp: the resolution and fovy of its
// entry, principal point at the centre, no distortion), through the camera's intrinsics when it has some.
class Undistortion {
 public:
  // `intrinsics` null: the identity (frames must be the pinhole's size). Throws InputError when the intrinsics
  // cannot be used (a singular camera matrix).
  Undistortion(const models::CameraSpec& camera, const Intrinsics* intrinsics);
  // The size the camera's frames must have.
  cv::Size input_size() const { return input_; }
  // The frame in the cell camera's pinhole (8-bit BGR); `raw` must be input_size().
  cv::Mat apply(const cv::Mat& raw) const;

 private:
  cv::Size input_, output_;
  cv::Mat map1_, map2_;  // empty: the identity
};

class CameraSource final : public runtime::FrameSource {
 public:
  // How long capture() waits for a live camera's next frame before calling it lost.
  static constexpr std::chrono::milliseconds kDeviceWait{500};

  // Opens `text` for the cell camera `camera` (its intrinsics file, if any, read here) and reads its first frame,
  // which must be the size the camera's frames have. InputError naming the device, file or glob: it cannot be opened,
  // a glob matches nothing, a recording without a rate, a first frame that does not come or is of another size.
  CameraSource(const CameraText& text, const models::CameraSpec& camera);
  ~CameraSource() override;
  CameraSource(const CameraSource&) = delete;
  CameraSource& operator=(const CameraSource&) = delete;

  std::optional<runtime::Image> capture(runtime::SimDuration t, std::string* why) override;

  // The first frame, in the cell camera's pinhole (what `twin calibrate` looks at).
  const cv::Mat& first_frame() const { return first_; }
  const CameraText& text() const { return text_; }
  bool live() const { return text_.kind == CameraText::Kind::kDevice; }
  // A recording's frames per second (0 for a live camera).
  double fps() const { return fps_; }

 private:
  // A recording's frame `index`, raw; nullopt past its end (the reason in *why).
  std::optional<cv::Mat> recorded(std::int64_t index, std::string* why);
  std::optional<cv::Mat> live_frame(std::string* why);
  std::optional<runtime::Image> deliver(const cv::Mat& raw, std::string* why) const;
  void read_device();

  CameraText text_;
  std::string camera_;
  std::unique_ptr<Undistortion> undistort_;
  std::unique_ptr<FrameGrabber> grabber_;
  std::vector<std::string> files_;  // an image sequence, sorted
  double fps_ = 0;
  cv::Mat first_;
  // A video: the frames read so far, the newest kept.
  std::int64_t read_ = 0;  // frames read
  cv::Mat last_;           // frame read_ - 1
  std::string ended_;      // why the recording has no more frames ("" while it has)
  // A live camera: the reader thread's newest frame.
  std::mutex mutex_;
  std::condition_variable changed_;
  cv::Mat newest_;
  std::uint64_t newest_seq_ = 0, delivered_seq_ = 0;
  std::string device_problem_;
  std::atomic<bool> stop_{false};
  std::thread reader_;
};

// A frame from any source as 8-bit BGR (grey and BGRA converted); InternalError for another depth.
cv::Mat as_bgr(const cv::Mat& frame);

}  // namespace cellwright::vision
