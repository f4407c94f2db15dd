#include "cellwright/vision/frame_grabber.hpp"

#include <dlfcn.h>

#include <fmt/format.h>


#include "cellwright/common/error.hpp"

#ifndef CW_VIDEO_CAPTURE_MODULE
#error "CW_VIDEO_CAPTURE_MODULE (the path of libcellwright_video_capture.so) must be defined by the build"
#endif

namespace cellwright::vision {

namespace {

using OpenFn = FrameGrabber* (*)(const char*, int, std::string*);
using ReadFn = bool (*)(const char*, cv::Mat*, std::string*);

struct Module {
  OpenFn open = nullptr;
  ReadFn read = nullptr;
  std::string problem;  // why it could not be loaded
};

// Loaded once, on first use, and kept for the life of the process.
const Module& module() {
  static const Module m = [] {
    Module out;
    void* handle = dlopen(CW_VIDEO_CAPTURE_MODULE, RTLD_NOW | RTLD_LOCAL);
    if (handle == nullptr) {
      const char* e = dlerror();
      out.problem = fmt::format("cannot load the camera module {}: {}", CW_VIDEO_CAPTURE_MODULE,
                                e != nullptr ? e : "unknown reason");
      return out;
    }
    out.open = reinterpret_cast<OpenFn>(dlsym(handle, "cellwright_open_grabber"));
    out.read = reinterpret_cast<ReadFn>(dlsym(handle, "cellwright_read_image"));
    if (out.open == nullptr || out.read == nullptr) {
      out.problem = fmt::format("the camera module {} lacks its entry points", CW_VIDEO_CAPTURE_MODULE);
    }
    return out;
  }();
  return m;
}

const Module& loaded(const std::string& path) {
  const Module& m = module();
  if (!m.problem.empty()) throw InputError({path, 0, 0}, m.problem);
  return m;
}

}  // namespace

std::unique_ptr<FrameGrabber> open_grabber(const std::string& path, bool device) {
  const Module& m = loaded(path);
  std::string error;
  std::unique_ptr<FrameGrabber> g(m.open(path.c_str(), device ? 1 : 0, &error));
  if (!g) throw InputError({path, 0, 0}, error);
  return g;
}

cv::Mat read_image(const std::string& path) {
  const Module& m = loaded(path);
  cv::Mat out;
  std::string error;
  if (!m.read(path.c_str(), &out, &error)) throw InputError({path, 0, 0}, error);
  return out;
}

}  // namespace cellwright::vision
