// The module behind frame_grabber.hpp: cv::VideoCapture and cv::imread, loaded by dlopen only when a real camera is
// opened (frame_grabber.hpp says why). Its two entry points have C names so that dlsym finds them; they throw
// nothing across the boundary: a failure is a null result and the reason in *error.
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>

#include <exception>
#include <string>

#include "cellwright/vision/frame_grabber.hpp"

namespace {

class VideoGrabber final : public cellwright::vision::FrameGrabber {
 public:
  explicit VideoGrabber(cv::VideoCapture capture) : capture_(std::move(capture)) {}
  bool read(cv::Mat& bgr) override {
    try {
      return capture_.read(bgr) && !bgr.empty();
    } catch (const std::exception&) {
      return false;  // a device gone or a damaged file: no more frames
    }
  }
  double fps() const override { return capture_.get(cv::CAP_PROP_FPS); }

 private:
  mutable cv::VideoCapture capture_;
};

}  // namespace

extern "C" {

cellwright::vision::FrameGrabber* cellwright_open_grabber(const char* path, int device, std::string* error);
bool cellwright_read_image(const char* path, cv::Mat* out, std::string* error);

// A grabber for `path` (a device with `device` != 0), or nullptr with the reason in *error.
__attribute__((visibility("default"))) cellwright::vision::FrameGrabber* cellwright_open_grabber(const char* path,
                                                                                                  int device,
                                                                                                  std::string* error) {
  try {
    cv::VideoCapture capture;
    const bool opened = device != 0 ? capture.open(path, cv::CAP_V4L2) : capture.open(path, cv::CAP_FFMPEG);
    if (!opened || !capture.isOpened()) {
      *error = device != 0 ? "cannot open the video device (OpenCV's V4L2 backend)"
                           : "cannot open the video file (OpenCV's FFmpeg backend: missing, or not a video it reads)";
      return nullptr;
    }
    return new VideoGrabber(std::move(capture));
  } catch (const std::exception& e) {
    *error = e.what();
    return nullptr;
  }
}

// `path` read as 8-bit BGR into *out; false with the reason in *error.
__attribute__((visibility("default"))) bool cellwright_read_image(const char* path, cv::Mat* out, std::string* error) {
  try {
    *out = cv::imread(path, cv::IMREAD_COLOR);
    if (out->empty()) *error = "cannot read the image (OpenCV's imgcodecs: missing, or not an image it reads)";
    return !out->empty();
  } catch (const std::exception& e) {
    *error = e.what();
    return false;
  }
}

}  // extern "C"
