// Offscreen snapshots of a scene, headless: software OpenGL through OSMesa, no display and no GPU.
//
// MuJoCo 2.2.2 loads its OpenGL functions at run time from whatever context is current when mjr_makeContext runs;
// the Renderer makes an OSMesa context current first, so MuJoCo renders with OSMesa whatever MUJOCO_GL says.
// The program does not link OSMesa: the first Renderer loads it (Mesa's llvmpipe brings libLLVM, whose loading cost
// every process about 0.1 s of CPU, rendering or not), and a library that cannot be loaded is its runtime_error.
//
// Threads: an OpenGL context is bound to one thread. A Renderer is created, used and destroyed on one thread (its
// methods check this and throw InternalError otherwise); several Renderers may live on different threads. Rendering
// reads the mjData (MuJoCo's mjv_updateScene takes it non-const and uses its scratch stack), so no other thread may
// use that mjData meanwhile.
#pragma once

#include <mujoco/mujoco.h>

#include <opencv2/core.hpp>

#include <filesystem>
#include <vector>
#include <memory>
#include <string_view>
#include <thread>

#include "cellwright/vision/camera_model.hpp"

namespace cellwright::twin {

class Scene;

// How much of MuJoCo's rendering a picture gets.
enum class RenderQuality {
  kFull,    // everything: shadows, reflections, the skybox; pictures for people (snapshots, reports)
  kVision,  // no shadows, reflections or skybox: the cheaper picture image processing works from (it needs the
            // parts' colours and outlines, not the light's effects); render_bench and vision_bench measure both
};

class Renderer {
 public:
  // An OSMesa context and MuJoCo's rendering context for `model`, able to render images up to max_width x
  // max_height pixels. `model` must outlive the Renderer. Throws std::runtime_error if OSMesa cannot be loaded, no
  // OpenGL context can be made or MuJoCo cannot render offscreen with it; InternalError if a size is not positive.
  Renderer(const mjModel* model, int max_width, int max_height);
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  int max_width() const { return max_width_; }
  int max_height() const { return max_height_; }

  // Renders `data` (made for this renderer's model) seen by the model's camera `camera_id`, as a BGR image (OpenCV's
  // channel order) of width x height pixels, top row first. Geoms whose colour the run changed (a processed part:
  // mjData::userdata, scene.hpp kColourSlot) are drawn in that colour; this holds for every render below. The camera's vertical field of view spans the image
  // height. width and height must be within 1..max (else InternalError).
  cv::Mat render_camera(mjData* data, int camera_id, int width, int height,
                        RenderQuality quality = RenderQuality::kFull);

  // As render_camera, from a free camera that frames the whole cell from above and in front, at an angle.
  cv::Mat render_overview(mjData* data, int width, int height);

  // The free camera render_overview uses for `data`'s state at width x height (it frames where the bodies are now);
  // a video keeps the first frame's, so that the view does not move with the robots.
  mjvCamera overview_camera(const mjData* data, int width, int height) const;
  // As render_camera, from any MuJoCo camera.
  cv::Mat render(mjData* data, const mjvCamera& camera, int width, int height,
                 RenderQuality quality = RenderQuality::kFull);

 private:

  struct Impl;
  std::unique_ptr<Impl> impl_;
  const mjModel* model_;
  int max_width_, max_height_;
  std::thread::id owner_;
};

// The name that selects render_overview in render_view and `twin snapshot --camera`.
inline constexpr std::string_view kOverviewCamera = "overview";

// Renders the scene's camera `camera` (kOverviewCamera for the overview) at width x height; a renderer of that size
// is made for the call. Throws InputError if the scene has no such camera (naming the cameras it has), or if width or
// height is not within 1..4096; otherwise as Renderer.
cv::Mat render_view(Scene& scene, std::string_view camera, int width, int height);

// A camera as MuJoCo has it: pose from data->cam_xpos / cam_xmat (valid after mj_forward or mj_kinematics) and
// model->cam_fovy, at width x height pixels. For a cell camera this agrees with vision::CameraModel(spec).
vision::CameraModel camera_model(const mjModel* model, const mjData* data, int camera_id, int width, int height);

// The camera Renderer::render_overview frames for `data` at width x height, as a CameraModel: to project world points
// (a workpiece's centre, say) onto the overview image.
vision::CameraModel overview_camera_model(const mjModel* model, const mjData* data, int width, int height);

}  // namespace cellwright::twin
