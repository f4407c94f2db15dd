// Offscreen rendering speed of the paper's cell (scenes/cell.yaml) with OSMesa, software OpenGL, no display.
// Run: MUJOCO_GL=osmesa build/tools/render_bench. The Time column is milliseconds per frame (wall clock: OSMesa may
// render on several threads); frames/s is its inverse. A frame is the scene update from mjData, the render and the
// read-back of the RGB pixels into an OpenCV image.
#include <benchmark/benchmark.h>

#include <filesystem>
#include <string>

#include "cellwright/models/cell.hpp"
#include "cellwright/twin/render.hpp"
#include "cellwright/twin/scene.hpp"

namespace {

using namespace cellwright;
using namespace cellwright::twin;

Scene& cell_scene() {
  static Scene scene = build_scene(models::load_cell(std::filesystem::path(CW_SOURCE_DIR) / "scenes" / "cell.yaml"));
  return scene;
}

void report(benchmark::State& state) {
  state.counters["frames/s"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}

// The overhead camera at 640 x 480, the picture the vision thread works from.
void BM_RenderOverhead(benchmark::State& state) {
  Scene& scene = cell_scene();
  const int w = static_cast<int>(state.range(0)), h = static_cast<int>(state.range(1));
  Renderer renderer(scene.model(), w, h);
  const int camera = scene.camera_id("overhead");
  renderer.render_camera(scene.data(), camera, w, h);  // warm up: llvmpipe compiles its shaders on first use
  for (auto _ : state) benchmark::DoNotOptimize(renderer.render_camera(scene.data(), camera, w, h).data);
  report(state);
}
BENCHMARK(BM_RenderOverhead)
    ->Args({640, 480})
    ->Args({320, 240})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MinTime(2.0);

// The free overview camera at 640 x 480: more of the cell in view, with shadows.
void BM_RenderOverview(benchmark::State& state) {
  Scene& scene = cell_scene();
  Renderer renderer(scene.model(), 640, 480);
  renderer.render_overview(scene.data(), 640, 480);
  for (auto _ : state) benchmark::DoNotOptimize(renderer.render_overview(scene.data(), 640, 480).data);
  report(state);
}
BENCHMARK(BM_RenderOverview)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(2.0);

// Making the OpenGL and MuJoCo rendering contexts, once per Renderer.
void BM_MakeRenderer(benchmark::State& state) {
  Scene& scene = cell_scene();
  for (auto _ : state) {
    Renderer renderer(scene.model(), 640, 480);
    benchmark::DoNotOptimize(&renderer);
  }
}
BENCHMARK(BM_MakeRenderer)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
