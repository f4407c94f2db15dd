// FrameGrabber: OpenCV's VideoCapture and image reading, kept out of every process that does not use a real camera.
//
// OpenCV's videoio (and the imgcodecs it needs) loads FFmpeg, GStreamer, GDAL and two hundred more libraries: linked
// into `twin`, every run would start 0.3 s later and hold 56 MB more (docs/simulation.md, "Memory"). So they live
// in a module of their own (vision/module/video_capture.cpp, built as libcellwright_video_capture.so beside the
// libraries) that open_grabber() loads with dlopen the first time a real camera is opened, and never unloads.
//
// Threads: open_grabber() and read_image() may be called from any thread; a FrameGrabber is used by one thread at a
// time.
#pragma once

#include <opencv2/core.hpp>

#include <memory>
#include <string>

namespace cellwright::vision {

class FrameGrabber {
 public:
  virtual ~FrameGrabber() = default;
  // The next frame, 8-bit BGR; false at the end of a file, or when a device stops delivering.
  virtual bool read(cv::Mat& bgr) = 0;
  // Frames per second as the file or device says (0 when it does not).
  virtual double fps() const = 0;
};

// Opens a video file, or a V4L2 device (`device`: a path such as /dev/video0) through cv::VideoCapture. Throws
// InputError naming `path` when it cannot be opened (or the module cannot be loaded).
std::unique_ptr<FrameGrabber> open_grabber(const std::string& path, bool device);

// Reads an image file as 8-bit BGR (cv::imread). Throws InputError naming `path` when it cannot.
cv::Mat read_image(const std::string& path);

}  // namespace cellwright::vision
