// Real cameras as the runtime's frame source (issue 26; vision/camera_source.hpp): --camera texts, OpenCV's
// intrinsics files, recordings (image files and a video, read through the module that holds OpenCV's VideoCapture)
// delivering frame round(t * fps) at time t and nothing past their end, and frames undistorted into the cell camera's
// pinhole.
#include "cellwright/vision/camera_source.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "cellwright/vision/cell_detector.hpp"
#include "cellwright/vision/png.hpp"

namespace cellwright::vision {
namespace {

using ::testing::HasSubstr;
namespace fs = std::filesystem;
using namespace std::chrono_literals;

class CameraSourceTest : public ::testing::Test {
 protected:
  CameraSourceTest() : dir_(fs::temp_directory_path() / ("cw-camera-source-" + std::to_string(::getpid()))) {
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    camera_.name = "overhead";
    camera_.width = 64;
    camera_.height = 48;
    camera_.fovy = 60 * M_PI / 180;
  }
  ~CameraSourceTest() override { fs::remove_all(dir_); }

  // Frame i of a recording: grey level 20 * (i + 1), so that a frame says which it is.
  void record(int frames) const {
    for (int i = 0; i < frames; ++i) {
      char name[32];
      std::snprintf(name, sizeof name, "frame_%06d.png", i);
      write_png(cv::Mat(camera_.height, camera_.width, CV_8UC3, cv::Scalar::all(20 * (i + 1))), dir_ / name);
    }
  }
  static int level(const runtime::Image& image) { return image.bgr.at(0); }
  std::string what(const std::string& text) const {
    try {
      CameraSource source(parse_camera_text(text, {"--camera", 0, 0}), camera_);
    } catch (const InputError& e) {
      return e.what();
    }
    return "no error";
  }

  fs::path dir_;
  models::CameraSpec camera_;
};

TEST(CameraText, ReadsDevicesAndRecordingsAndRefusesTheRest) {
  const CameraText d = parse_camera_text("overhead=v4l2:/dev/video2", {"--camera", 0, 0});
  EXPECT_EQ(d.camera, "overhead");
  EXPECT_EQ(d.kind, CameraText::Kind::kDevice);
  EXPECT_EQ(d.path, "/dev/video2");
  const CameraText f = parse_camera_text("top=file:rec/frame_*.png,fps=2.5", {"--camera", 0, 0});
  EXPECT_EQ(f.kind, CameraText::Kind::kFile);
  EXPECT_EQ(f.path, "rec/frame_*.png");
  EXPECT_TRUE(f.images());
  EXPECT_EQ(f.fps, 2.5);
  EXPECT_FALSE(parse_camera_text("top=file:run.mkv", {"--camera", 0, 0}).images());
  for (const auto& [text, says] : std::vector<std::pair<std::string, std::string>>{
           {"overhead", "no '='"},
           {"=file:x.mkv", "no camera name"},
           {"overhead=x.mkv", "no kind of source"},
           {"overhead=http:x", "unknown kind of source 'http'"},
           {"overhead=file:", "no file"},
           {"overhead=v4l2:/dev/video0,fps=5", "a device has its own rate"},
           {"overhead=file:x.mkv,fps=-1", "fps must be"},
           {"overhead=file:x.mkv,fps=fast", "fps must be"}}) {
    try {
      (void)parse_camera_text(text, {"--camera", 0, 0});
      ADD_FAILURE() << text << ": no error";
    } catch (const InputError& e) {
      EXPECT_THAT(e.what(), HasSubstr(says)) << text;
      EXPECT_THAT(e.what(), HasSubstr("--camera")) << text;
    }
  }
}

TEST_F(CameraSourceTest, AnImageRecordingGivesTheFrameOfTheRunsTimeAndNothingPastItsEnd) {
  record(5);
  CameraSource source(parse_camera_text("overhead=file:" + (dir_ / "frame_*.png").string() + ",fps=2.5",
                                        {"--camera", 0, 0}),
                      camera_);
  std::string why;
  // Frame i is the picture of time i / 2.5 s: the run's first frame (one control period in) is frame 0.
  for (const auto& [t, frame] : std::vector<std::pair<std::chrono::milliseconds, int>>{
           {10ms, 0}, {400ms, 1}, {800ms, 2}, {1600ms, 4}}) {
    const std::optional<runtime::Image> image = source.capture(t, &why);
    ASSERT_TRUE(image.has_value()) << t.count() << " ms: " << why;
    EXPECT_EQ(level(*image), 20 * (frame + 1)) << t.count() << " ms";
  }
  EXPECT_FALSE(source.capture(2000ms, &why).has_value());
  EXPECT_THAT(why, HasSubstr("ended after 5 frames (2.000 s at 2.5 fps)"));
}

// A video, made by FFmpeg from the same images (FFV1: lossless), read through VideoCapture: its rate is the file's.
TEST_F(CameraSourceTest, AVideoRecordingIsReadThroughVideoCaptureAtItsOwnRate) {
  record(4);
  const fs::path video = dir_ / "run.mkv";
  const std::string cmd = "ffmpeg -loglevel error -y -framerate 2.5 -i '" + (dir_ / "frame_%06d.png").string() +
                          "' -c:v ffv1 '" + video.string() + "'";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  CameraSource source(parse_camera_text("overhead=file:" + video.string(), {"--camera", 0, 0}), camera_);
  EXPECT_DOUBLE_EQ(source.fps(), 2.5);
  std::string why;
  for (int i = 0; i < 4; ++i) {
    const std::optional<runtime::Image> image = source.capture(std::chrono::milliseconds(400 * i + 10), &why);
    ASSERT_TRUE(image.has_value()) << i << ": " << why;
    EXPECT_NEAR(level(*image), 20 * (i + 1), 1) << i;
  }
  EXPECT_FALSE(source.capture(1600ms, &why).has_value());
  EXPECT_THAT(why, HasSubstr("ended after 4 frames"));
  EXPECT_FALSE(source.capture(2000ms, &why).has_value());  // and stays ended
}

TEST_F(CameraSourceTest, RefusesWhatItCannotOpenNamingIt) {
  record(1);
  EXPECT_THAT(what("overhead=file:" + (dir_ / "none.mkv").string()), HasSubstr("none.mkv"));
  EXPECT_THAT(what("overhead=file:" + (dir_ / "none.mkv").string()), HasSubstr("no such file"));
  EXPECT_THAT(what("overhead=file:" + (dir_ / "x_*.png").string() + ",fps=1"), HasSubstr("no file matches"));
  EXPECT_THAT(what("overhead=file:" + (dir_ / "frame_*.png").string()), HasSubstr("needs its rate"));
  EXPECT_THAT(what("overhead=v4l2:/dev/cellwright_no_video"), HasSubstr("no such device"));
  camera_.width = 80;  // the frames are 64 x 48
  EXPECT_THAT(what("overhead=file:" + (dir_ / "frame_*.png").string() + ",fps=1"),
              HasSubstr("its frames are 64 x 48 pixels, and camera 'overhead' takes 80 x 48"));
}

TEST_F(CameraSourceTest, ReadsOpenCVsIntrinsicsFileAndNamesWhatIsMissing) {
  const fs::path file = dir_ / "intrinsics.yaml";
  {
    cv::FileStorage fs(file.string(), cv::FileStorage::WRITE);
    fs << "image_width" << 640 << "image_height" << 480;
    fs << "camera_matrix" << cv::Mat(cv::Matx33d(500, 0, 320, 0, 500, 240, 0, 0, 1));
    fs << "distortion_coefficients" << cv::Mat(cv::Matx<double, 5, 1>(-0.2, 0.05, 0, 0, 0));
  }
  const Intrinsics in = read_intrinsics(file);
  EXPECT_EQ(in.size, cv::Size(640, 480));
  EXPECT_EQ(in.camera_matrix(0, 0), 500);
  EXPECT_EQ(in.distortion.size(), 5u);
  EXPECT_EQ(in.distortion[0], -0.2);
  const fs::path bad = dir_ / "bad.yaml";
  {
    cv::FileStorage fs(bad.string(), cv::FileStorage::WRITE);
    fs << "image_width" << 640 << "image_height" << 480;
    fs << "camera_matrix" << cv::Mat(cv::Matx33d(500, 0, 320, 0, 500, 240, 0, 0, 1));
  }
  try {
    (void)read_intrinsics(bad);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("bad.yaml"));
    EXPECT_THAT(e.what(), HasSubstr("no 'distortion_coefficients'"));
  }
}

// A lens that bends straight lines: a frame made through it is undistorted into the cell camera's pinhole, where a
// point lands on the pixel the pinhole projects it to.
TEST_F(CameraSourceTest, UndistortsIntoTheCellCamerasPinhole) {
  camera_.width = 640;
  camera_.height = 480;
  const Eigen::Matrix3d k = CameraModel(camera_).intrinsics();
  const cv::Matx33d ideal(k(0, 0), 0, k(0, 2), 0, k(1, 1), k(1, 2), 0, 0, 1);
  Intrinsics lens;
  lens.camera_matrix = cv::Matx33d(520, 0, 330, 0, 515, 236, 0, 0, 1);
  lens.distortion = {-0.25, 0.08, 0.001, -0.002, 0};
  lens.size = {640, 480};
  // The real camera's picture of a white dot that the pinhole sees at `at`: where the lens puts it.
  const cv::Point2d at(470.0, 120.0);
  std::vector<cv::Point3d> ray = {{(at.x - ideal(0, 2)) / ideal(0, 0), (at.y - ideal(1, 2)) / ideal(1, 1), 1.0}};
  std::vector<cv::Point2d> through_lens;
  cv::projectPoints(ray, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), lens.camera_matrix, lens.distortion, through_lens);
  cv::Mat raw(480, 640, CV_8UC3, cv::Scalar::all(0));
  cv::circle(raw, cv::Point(cvRound(through_lens[0].x * 16), cvRound(through_lens[0].y * 16)), 4 * 16,
             cv::Scalar::all(255), cv::FILLED, cv::LINE_AA, 4);
  const Undistortion u(camera_, &lens);
  EXPECT_EQ(u.input_size(), cv::Size(640, 480));
  cv::Mat grey;
  cv::cvtColor(u.apply(raw), grey, cv::COLOR_BGR2GRAY);
  const cv::Moments m = cv::moments(grey);
  ASSERT_GT(m.m00, 0);
  EXPECT_NEAR(m.m10 / m.m00, at.x, 0.3);
  EXPECT_NEAR(m.m01 / m.m00, at.y, 0.3);
  // Without intrinsics the frame passes unchanged.
  const Undistortion none(camera_, nullptr);
  EXPECT_EQ(cv::norm(none.apply(raw), raw, cv::NORM_INF), 0);
}

}  // namespace
}  // namespace cellwright::vision
