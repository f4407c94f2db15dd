// Vision on the paper's cell (issue 5): accuracy of the workpiece detector against MuJoCo's ground truth and the cost
// of a frame (render + detection), at 640 x 480 from the overhead camera.
// Run: MUJOCO_GL=osmesa build/tools/vision_bench.
//
// Accuracy: seeded random placements (one part, chosen at random, on the machine's fixture, the others anywhere on
// the input belt, clear of each other, turned at random), each rendered and searched; every part's detected centre
// and yaw against the truth in mjData. Targets: median position error <= 2 mm, median orientation error <= 2 deg.
// Printed for the cheap vision render (RenderQuality::kVision) and the full one (shadows, reflections, skybox).
//
// Cost: per frame, wall time and CPU time of the whole process (OSMesa's llvmpipe renders on worker threads, so the
// CPU time of the calling thread alone would miss most of it). Target: render + detection <= 30 ms. The benchmarks
// give the same figures with Google Benchmark's statistics (cpu_ms is the process's CPU time per frame).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "cellwright/models/cell.hpp"
#include "cellwright/twin/render.hpp"
#include "cellwright/twin/scene.hpp"
#include "cellwright/vision/detector.hpp"

namespace {

using namespace cellwright;
using namespace cellwright::twin;

constexpr int kWidth = 640, kHeight = 480;
constexpr unsigned kSeed = 1;
constexpr int kPlacements = 200;
constexpr double kPi = std::numbers::pi;

const models::CellDescription& cell() {
  static const models::CellDescription c =
      models::load_cell(std::filesystem::path(CW_SOURCE_DIR) / "scenes" / "cell.yaml");
  return c;
}

double process_cpu_ms() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return 1e3 * static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_nsec);
}

double wall_ms() {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

void place(Scene& s, const std::string& name, const Eigen::Vector3d& bottom, double yaw) {
  const WorkpieceIds& w = *s.find_workpiece(name);
  mjtNum* q = s.data()->qpos + w.qpos_adr;
  q[0] = bottom.x();
  q[1] = bottom.y();
  q[2] = bottom.z() + s.cell().find_workpiece(name)->size.z() / 2;
  q[3] = std::cos(yaw / 2);
  q[4] = 0;
  q[5] = 0;
  q[6] = std::sin(yaw / 2);
  for (int i = 0; i < 6; ++i) s.data()->qvel[w.dof_adr + i] = 0;
}

// One random placement of every workpiece (see the top of the file).
void random_placement(Scene& s, std::mt19937& rng) {
  const models::ConveyorSpec& belt = *s.cell().find_conveyor("input");
  const models::MachineSpec& mill = *s.cell().find_machine("mill");
  const auto& parts = s.cell().workpieces;
  std::uniform_real_distribution<double> unit(0, 1);
  std::vector<std::size_t> order(parts.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::shuffle(order.begin(), order.end(), rng);
  std::vector<std::pair<Eigen::Vector2d, double>> taken;
  for (std::size_t k = 0; k < order.size(); ++k) {
    const models::WorkpieceSpec& w = parts[order[k]];
    const double radius = 0.5 * w.size.head<2>().norm();
    const double yaw = 2 * kPi * unit(rng);
    if (k == 0) {
      const models::Pose top = mill.fixture_top();
      const Eigen::Vector2d room = mill.fixture_size.head<2>() / 2 - w.size.head<2>() / 2;
      place(s, w.name, top.xyz + Eigen::Vector3d(room.x() * (2 * unit(rng) - 1), room.y() * (2 * unit(rng) - 1), 0),
            yaw);
      continue;
    }
    for (;;) {
      const double along = radius + (belt.leave - 2 * radius) * unit(rng);
      const double across = (belt.width / 2 - radius) * (2 * unit(rng) - 1);
      const Eigen::Vector3d p = belt.pose.transform() * Eigen::Vector3d(along - belt.length / 2, across, belt.height);
      bool clear = true;
      for (const auto& [c, r] : taken) clear = clear && (p.head<2>() - c).norm() > r + radius + 0.005;
      if (!clear) continue;
      taken.emplace_back(p.head<2>(), radius);
      place(s, w.name, p, yaw);
      break;
    }
  }
  mj_forward(s.model(), s.data());
}

struct Errors {
  std::vector<double> position_mm, yaw_deg;
  int parts = 0, found = 0, rejected = 0;
  std::vector<double> render_wall, render_cpu, detect_wall, detect_cpu;
};

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(std::lround(p * static_cast<double>(v.size() - 1)))];
}

Errors measure(RenderQuality quality) {
  Scene s = build_scene(cell());
  Renderer renderer(s.model(), kWidth, kHeight);
  const vision::Detector detector(cell(), vision::CameraModel(*cell().find_camera("overhead")));
  const int camera = s.camera_id("overhead");
  // Warm up: llvmpipe compiles its shaders, OpenCV starts its threads, on first use.
  vision::detect(detector, renderer.render_camera(s.data(), camera, kWidth, kHeight, quality));
  std::mt19937 rng(kSeed);
  Errors e;
  for (int i = 0; i < kPlacements; ++i) {
    random_placement(s, rng);
    double w0 = wall_ms(), c0 = process_cpu_ms();
    const cv::Mat image = renderer.render_camera(s.data(), camera, kWidth, kHeight, quality);
    double w1 = wall_ms(), c1 = process_cpu_ms();
    const vision::DetectionResult found = vision::detect(detector, image);
    double w2 = wall_ms(), c2 = process_cpu_ms();
    e.render_wall.push_back(w1 - w0);
    e.render_cpu.push_back(c1 - c0);
    e.detect_wall.push_back(w2 - w1);
    e.detect_cpu.push_back(c2 - c1);
    e.parts += static_cast<int>(cell().workpieces.size());
    e.found += static_cast<int>(found.detections.size());
    e.rejected += static_cast<int>(found.rejected.size());
    for (const vision::Detection& d : found.detections) {
      const WorkpieceIds& w = *s.find_workpiece(d.workpiece);
      const Eigen::Vector3d truth(s.data()->xpos[3 * w.body], s.data()->xpos[3 * w.body + 1],
                                  s.data()->xpos[3 * w.body + 2]);
      e.position_mm.push_back(1e3 * (d.position - truth).norm());
      if (d.yaw) {
        const mjtNum* r = s.data()->xmat + 9 * w.body;
        double err = std::fmod(*d.yaw - std::atan2(r[3], r[0]), d.yaw_period);
        if (err < 0) err += d.yaw_period;
        if (err > d.yaw_period / 2) err -= d.yaw_period;
        e.yaw_deg.push_back(std::abs(err) * 180 / kPi);
      }
    }
  }
  return e;
}

void print(const char* name, const Errors& e) {
  auto mean = [](const std::vector<double>& v) {
    double s = 0;
    for (double x : v) s += x;
    return v.empty() ? 0.0 : s / static_cast<double>(v.size());
  };
  std::printf("\n%s render, %d placements (seed %u), %d parts: %d found, %d blobs rejected\n", name, kPlacements, kSeed,
              e.parts, e.found, e.rejected);
  std::printf("  position error  median %.2f mm   p95 %.2f mm   max %.2f mm   (target: median <= 2 mm)\n",
              percentile(e.position_mm, 0.5), percentile(e.position_mm, 0.95), percentile(e.position_mm, 1));
  std::printf("  yaw error       median %.2f deg  p95 %.2f deg  max %.2f deg  (target: median <= 2 deg; boxes only)\n",
              percentile(e.yaw_deg, 0.5), percentile(e.yaw_deg, 0.95), percentile(e.yaw_deg, 1));
  std::printf(
      "  per frame       render %.1f ms wall / %.1f ms cpu, detect %.1f ms wall / %.1f ms cpu, "
      "total %.1f ms wall (p95 %.1f)   (target: total <= 30 ms)\n",
      mean(e.render_wall), mean(e.render_cpu), mean(e.detect_wall), mean(e.detect_cpu),
      mean(e.render_wall) + mean(e.detect_wall), percentile(e.render_wall, 0.95) + percentile(e.detect_wall, 0.95));
}

// --- Google Benchmark: the same costs with its statistics ---

struct Frames {
  Scene scene = build_scene(cell());
  std::vector<std::vector<double>> qpos;  // placements to cycle through
  Frames() {
    std::mt19937 rng(kSeed);
    for (int i = 0; i < 20; ++i) {
      random_placement(scene, rng);
      qpos.emplace_back(scene.data()->qpos, scene.data()->qpos + scene.model()->nq);
    }
  }
  void use(std::size_t i) {
    std::copy(qpos[i % qpos.size()].begin(), qpos[i % qpos.size()].end(), scene.data()->qpos);
    mj_forward(scene.model(), scene.data());
  }
};

Frames& frames() {
  static Frames f;
  return f;
}

void cpu_counter(benchmark::State& state, double cpu_total) {
  state.counters["cpu_ms"] = benchmark::Counter(cpu_total / static_cast<double>(state.iterations()));
}

void BM_Render(benchmark::State& state) {
  const RenderQuality quality = state.range(0) == 0 ? RenderQuality::kFull : RenderQuality::kVision;
  state.SetLabel(quality == RenderQuality::kFull ? "full" : "vision");
  Frames& f = frames();
  Renderer renderer(f.scene.model(), kWidth, kHeight);
  const int camera = f.scene.camera_id("overhead");
  renderer.render_camera(f.scene.data(), camera, kWidth, kHeight, quality);
  std::size_t i = 0;
  double cpu = 0;
  for (auto _ : state) {
    state.PauseTiming();
    f.use(i++);
    state.ResumeTiming();
    const double c0 = process_cpu_ms();
    benchmark::DoNotOptimize(renderer.render_camera(f.scene.data(), camera, kWidth, kHeight, quality).data);
    cpu += process_cpu_ms() - c0;
  }
  cpu_counter(state, cpu);
}
BENCHMARK(BM_Render)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(2.0);

void BM_Detect(benchmark::State& state) {
  Frames& f = frames();
  Renderer renderer(f.scene.model(), kWidth, kHeight);
  const vision::Detector detector(cell(), vision::CameraModel(*cell().find_camera("overhead")));
  std::vector<cv::Mat> images;
  for (std::size_t i = 0; i < f.qpos.size(); ++i) {
    f.use(i);
    images.push_back(
        renderer.render_camera(f.scene.data(), f.scene.camera_id("overhead"), kWidth, kHeight, RenderQuality::kVision));
  }
  vision::detect(detector, images.front());
  std::size_t i = 0;
  const double start = process_cpu_ms();
  for (auto _ : state) benchmark::DoNotOptimize(vision::detect(detector, images[i++ % images.size()]).detections);
  cpu_counter(state, process_cpu_ms() - start);
}
BENCHMARK(BM_Detect)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(2.0);

void BM_RenderAndDetect(benchmark::State& state) {
  Frames& f = frames();
  Renderer renderer(f.scene.model(), kWidth, kHeight);
  const vision::Detector detector(cell(), vision::CameraModel(*cell().find_camera("overhead")));
  const int camera = f.scene.camera_id("overhead");
  vision::detect(detector, renderer.render_camera(f.scene.data(), camera, kWidth, kHeight, RenderQuality::kVision));
  std::size_t i = 0;
  double cpu = 0;
  for (auto _ : state) {
    state.PauseTiming();
    f.use(i++);
    state.ResumeTiming();
    const double c0 = process_cpu_ms();
    const cv::Mat image = renderer.render_camera(f.scene.data(), camera, kWidth, kHeight, RenderQuality::kVision);
    benchmark::DoNotOptimize(vision::detect(detector, image).detections);
    cpu += process_cpu_ms() - c0;
  }
  cpu_counter(state, cpu);
}
BENCHMARK(BM_RenderAndDetect)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(2.0);

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  print("vision (no shadows, reflections, skybox)", measure(RenderQuality::kVision));
  print("full", measure(RenderQuality::kFull));
  return 0;
}
