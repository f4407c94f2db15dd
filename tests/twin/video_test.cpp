// The video of a run (video.hpp): what a browser needs (H.264, yuv420p, MP4), the frames at the rate asked, the
// overlay drawn on them, bad files refused before anything runs, and a run's event log the same with and without.
#include "cellwright/cell/preflight.hpp"
#include "cellwright/cell/sim/sweep.hpp"
#include "cellwright/twin/video.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libswscale/swscale.h>
}

#include <opencv2/imgproc.hpp>

#include <filesystem>
#include <string>
#include <vector>

#include "cellwright/common/error.hpp"
#include "cellwright/common/files.hpp"
#include "cellwright/models/cell.hpp"
#include "cellwright/twin/render.hpp"
#include "cellwright/cell/sim/run.hpp"
#include "cellwright/twin/scene.hpp"
#include "cellwright/twin/sim/world.hpp"

namespace cellwright::twin {
namespace {

namespace fs = std::filesystem;

const std::string kScenes = std::string(CW_SOURCE_DIR) + "/scenes";

// What a player finds in the file: the container's view of the stream, and every frame decoded (BGR).
struct Decoded {
  std::string format;  // the container's names, "mov,mp4,m4a,3gp,3g2,mj2"
  AVCodecID codec = AV_CODEC_ID_NONE;
  int pixel_format = -1;
  int width = 0, height = 0;
  double fps = 0;
  std::int64_t stream_frames = 0;  // as the container's index says
  bool index_first = false;        // the 'moov' box before 'mdat' (+faststart)
  std::vector<cv::Mat> frames;
};

Decoded decode(const fs::path& path) {
  Decoded out;
  AVFormatContext* format = nullptr;
  if (avformat_open_input(&format, path.c_str(), nullptr, nullptr) < 0) return out;
  avformat_find_stream_info(format, nullptr);
  out.format = format->iformat->name;
  const int index = av_find_best_stream(format, AVMEDIA_TYPE_VIDEO, -1, -1, nullptr, 0);
  if (index >= 0) {
    const AVStream* stream = format->streams[index];
    out.codec = stream->codecpar->codec_id;
    out.pixel_format = stream->codecpar->format;
    out.width = stream->codecpar->width;
    out.height = stream->codecpar->height;
    out.fps = av_q2d(stream->avg_frame_rate);
    out.stream_frames = stream->nb_frames;
    const AVCodec* codec = avcodec_find_decoder(out.codec);
    AVCodecContext* context = avcodec_alloc_context3(codec);
    avcodec_parameters_to_context(context, stream->codecpar);
    avcodec_open2(context, codec, nullptr);
    AVPacket* packet = av_packet_alloc();
    AVFrame* frame = av_frame_alloc();
    SwsContext* scale = nullptr;
    auto drain = [&] {
      while (avcodec_receive_frame(context, frame) == 0) {
        scale = sws_getCachedContext(scale, frame->width, frame->height, static_cast<AVPixelFormat>(frame->format),
                                     frame->width, frame->height, AV_PIX_FMT_BGR24, SWS_BILINEAR, nullptr, nullptr,
                                     nullptr);
        cv::Mat bgr(frame->height, frame->width, CV_8UC3);
        std::uint8_t* const dst[1] = {bgr.data};
        const int stride[1] = {static_cast<int>(bgr.step[0])};
        sws_scale(scale, frame->data, frame->linesize, 0, frame->height, dst, stride);
        out.frames.push_back(bgr);
      }
    };
    while (av_read_frame(format, packet) >= 0) {
      if (packet->stream_index == index) {
        avcodec_send_packet(context, packet);
        drain();
      }
      av_packet_unref(packet);
    }
    avcodec_send_packet(context, nullptr);
    drain();
    sws_freeContext(scale);
    av_frame_free(&frame);
    av_packet_free(&packet);
    avcodec_free_context(&context);
  }
  avformat_close_input(&format);
  const std::string bytes = read_file(path);
  const auto moov = bytes.find("moov"), mdat = bytes.find("mdat");
  out.index_first = moov != std::string::npos && mdat != std::string::npos && moov < mdat;
  return out;
}

class Video : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           fmt::format("cw_video_{}_{}", ::getpid(), ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(Video, WriterMakesAnH264Yuv420pMp4WithEveryFrameAndItsIndexFirst) {
  VideoWriter writer;
  writer.open(dir_ / "bars.mp4", 160, 120, 10);
  for (int i = 0; i < 25; ++i) {
    cv::Mat image(120, 160, CV_8UC3, cv::Scalar(40, 40, 40));
    cv::rectangle(image, cv::Rect(i * 5, 30, 20, 60), cv::Scalar(0, 200, 255), cv::FILLED);
    writer.add(image);
  }
  EXPECT_EQ(writer.frames(), 25);
  writer.close();
  EXPECT_FALSE(writer.is_open());

  const Decoded d = decode(dir_ / "bars.mp4");
  EXPECT_NE(d.format.find("mp4"), std::string::npos) << d.format;
  EXPECT_EQ(d.codec, AV_CODEC_ID_H264);
  EXPECT_EQ(d.pixel_format, AV_PIX_FMT_YUV420P);
  EXPECT_EQ(d.width, 160);
  EXPECT_EQ(d.height, 120);
  EXPECT_DOUBLE_EQ(d.fps, 10.0);
  EXPECT_EQ(d.stream_frames, 25);
  ASSERT_EQ(d.frames.size(), 25u);
  EXPECT_TRUE(d.index_first) << "no +faststart: a browser must load the whole file before it plays";
  // The moving bar is where it was drawn, in the last frame as in the first (H.264 is lossy: colours approximately).
  const cv::Vec3b first = d.frames.front().at<cv::Vec3b>(60, 10), last = d.frames.back().at<cv::Vec3b>(60, 130);
  EXPECT_GT(first[2], 200);
  EXPECT_GT(last[2], 200);
  EXPECT_LT(d.frames.front().at<cv::Vec3b>(60, 130)[2], 100);
}

TEST_F(Video, WriterRefusesFilesItCannotWriteNamingThem) {
  auto refused = [](const fs::path& path, int w, int h, int fps, const std::string& why) {
    VideoWriter writer;
    try {
      writer.open(path, w, h, fps);
      ADD_FAILURE() << path << " " << w << "x" << h << " at " << fps << " was accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(path.string()), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(why), std::string::npos) << e.what();
    }
    EXPECT_FALSE(writer.is_open());
  };
  refused(dir_ / "missing" / "run.mp4", 160, 120, 20, "does not exist");
  refused(dir_ / "run.avi", 160, 120, 20, "must end in .mp4");
  refused(dir_ / "odd.mp4", 161, 120, 20, "even");
  refused(dir_ / "slow.mp4", 160, 120, 0, "1..120");
  fs::create_directories(dir_ / "dir.mp4");
  refused(dir_ / "dir.mp4", 160, 120, 20, "cannot write the video");
}

TEST_F(Video, OverlayDrawsTheTextOnADarkBandAndLeavesTheRestOfThePicture) {
  const cv::Mat plain(300, 400, CV_8UC3, cv::Scalar(180, 180, 180));
  cv::Mat drawn = plain.clone();
  draw_overlay(drawn, {{"t = 1.25 s", "r1: busy move at(A)"}, "", false});
  // The band is darker but for the white text in it; below it, nothing changed.
  const cv::Mat band = drawn(cv::Rect(0, 0, 120, 30));
  double lo = 0, hi = 0;
  cv::minMaxLoc(band.reshape(1), &lo, &hi);
  EXPECT_LT(lo, 80);
  EXPECT_GT(hi, 230);
  EXPECT_EQ(cv::norm(drawn(cv::Rect(0, 100, 400, 150)), plain(cv::Rect(0, 100, 400, 150)), cv::NORM_INF), 0);

  cv::Mat verdict = plain.clone();
  draw_overlay(verdict, {{}, "PASS: finished in 12.00 s", true});
  EXPECT_EQ(cv::norm(verdict(cv::Rect(0, 0, 400, 200)), plain(cv::Rect(0, 0, 400, 200)), cv::NORM_INF), 0);
  EXPECT_GT(cv::norm(verdict(cv::Rect(0, 250, 400, 50)), plain(cv::Rect(0, 250, 400, 50)), cv::NORM_INF), 100);
}

// A run recorded lock-step: the same events as without the video, a frame every 1/fps of simulated time from the
// first period on plus the verdict held `hold` s, and the frames are the cell with the text over it.
TEST_F(Video, ARunRecordsEveryFrameAndKeepsItsEventLog) {
  using namespace cell;
  const Scenario s = load_scenario(kScenes + "/single.yaml");
  const Preflight pre = preflight(s, &twin_port());
  ASSERT_TRUE(pre.ok()) << pre.problems.front();

  ScenarioRun plain(s, pre);
  ASSERT_EQ(plain.runtime().run().outcome, runtime::Outcome::kFinished);

  RunOptions options;
  VideoOptions video;
  video.path = dir_ / "single.mp4";
  video.fps = 4;
  video.width = 320;
  video.height = 240;
  video.hold = 1.0;
  options.video = video;
  ScenarioRun recorded(s, pre, options);
  ASSERT_TRUE(fs::exists(video.path)) << "the file is opened before the run";
  const runtime::RunResult result = recorded.runtime().run();
  ASSERT_EQ(result.outcome, runtime::Outcome::kFinished);
  EXPECT_EQ(recorded.runtime().log().text(), plain.runtime().log().text());
  const Report report = recorded.report();
  EXPECT_EQ(recorded.finish_video(report), video.path);
  EXPECT_TRUE(recorded.finish_video(report).empty()) << "finished once";

  // Frames at 0.25 s, 0.5 s, ... (the first period that reaches each), from the first period to the end, then 4.
  const double end = std::chrono::duration<double>(result.end_time).count();
  const auto expected = static_cast<std::size_t>(std::floor(end * video.fps + 1e-9)) + 1 + 4;
  const Decoded d = decode(video.path);
  EXPECT_EQ(d.codec, AV_CODEC_ID_H264);
  EXPECT_EQ(d.pixel_format, AV_PIX_FMT_YUV420P);
  ASSERT_EQ(d.frames.size(), expected) << "end " << end << " s";
  EXPECT_EQ(d.stream_frames, static_cast<std::int64_t>(expected));
}

// The frames are the cell as the overview camera shows it, with the time and the robots' commands written over the
// top left and the verdict across the bottom of the last ones.
TEST_F(Video, RecorderFramesAreTheCellWithTheTextOverIt) {
  Scene scene = build_scene(models::load_cell(kScenes + "/cell.yaml"));
  const mjModel* model = scene.model();
  mj_forward(model, scene.data());
  VideoOptions options;
  options.path = dir_ / "cell.mp4";
  options.fps = 10;
  options.width = 320;
  options.height = 240;
  options.hold = 0.5;
  {
    VideoRecorder recorder(model, options);
    EXPECT_EQ(recorder.frame_period(), std::chrono::milliseconds(100));
    for (int i = 0; i < 3; ++i) {
      recorder.record(scene.data(), std::chrono::milliseconds(100 * i), {"r1: busy move at(A)", "r2: waiting"});
    }
    recorder.finish(scene.data(), std::chrono::milliseconds(250), "PASS: finished in 0.25 s", true);
    EXPECT_EQ(recorder.frames(), 3 + 5);
  }
  Renderer renderer(model, 320, 240);
  const cv::Mat plain = renderer.render_overview(scene.data(), 320, 240);
  const Decoded d = decode(options.path);
  ASSERT_EQ(d.frames.size(), 8u);
  auto mean_difference = [&plain](const cv::Mat& frame, const cv::Rect& r) {
    cv::Mat diff;
    cv::absdiff(frame(r), plain(r), diff);
    const cv::Scalar m = cv::mean(diff);
    return (m[0] + m[1] + m[2]) / 3;
  };
  const cv::Rect middle(40, 90, 240, 100), text(0, 0, 110, 40), verdict(0, 215, 320, 25);
  for (const std::size_t i : {std::size_t{0}, std::size_t{7}}) {
    // The cell as rendered (H.264 is lossy: a few levels) ...
    EXPECT_LT(mean_difference(d.frames[i], middle), 4.0) << "frame " << i;
    // ... with the text over it.
    EXPECT_GT(mean_difference(d.frames[i], text), 20.0) << "frame " << i;
  }
  EXPECT_LT(mean_difference(d.frames[0], verdict), 4.0) << "no verdict while running";
  EXPECT_GT(mean_difference(d.frames[7], verdict), 20.0) << "the verdict on the last frames";
}

// What a viewer of a run with devices reads under the robots' lines: each machine's state with its part and the
// process time left, each conveyor running, stopped or held by a part at its stop, and its photo-eyes that see a part.
TEST(VideoDevices, EachMachineAndConveyorHasALineWithItsStateAndItsPart) {
  sim::DeviceStates d;
  sim::MachineDevice mill;
  mill.name = "mill";
  mill.state = sim::MachineState::busy;
  mill.part = "A";
  mill.busy_left = std::chrono::milliseconds(2400);
  sim::MachineDevice press;
  press.name = "press";
  press.state = sim::MachineState::done;
  press.part = "B";
  sim::MachineDevice drill;
  drill.name = "drill";
  d.machines = {mill, press, drill};
  sim::ConveyorDevice input;
  input.name = "input";
  input.run = true;
  input.running = false;
  input.stop_eye = true;
  sim::ConveyorDevice output;
  output.name = "output";
  output.run = false;
  output.running = false;
  output.drop_eye = true;
  sim::ConveyorDevice feed;
  feed.name = "feed";
  d.conveyors = {input, output, feed};
  EXPECT_EQ(device_lines(d), (std::vector<std::string>{"mill: busy A (2.4 s left)", "press: done B (to unload)",
                                                       "drill: idle", "input: held (accumulating), stop eye on",
                                                       "output: stopped, drop eye on", "feed: running"}));
  EXPECT_TRUE(device_lines(sim::DeviceStates{}).empty());
}

TEST_F(Video, AFileThatCannotBeWrittenIsRefusedBeforeTheRun) {
  using namespace cell;
  const Scenario s = load_scenario(kScenes + "/single.yaml");
  const Preflight pre = preflight(s, &twin_port());
  ASSERT_TRUE(pre.ok());
  RunOptions options;
  VideoOptions video;
  video.path = dir_ / "no" / "such" / "dir" / "run.mp4";
  options.video = video;
  try {
    ScenarioRun run(s, pre, options);
    FAIL() << "a video that cannot be written was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(video.path.string()), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace cellwright::twin
