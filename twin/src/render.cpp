// Offscreen rendering with OSMesa (render.hpp).
#include "cellwright/twin/render.hpp"

#include <GL/osmesa.h>
#include <dlfcn.h>

#include <opencv2/imgproc.hpp>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <stdexcept>
#include <vector>

#include "cellwright/common/error.hpp"
#include "cellwright/twin/scene.hpp"

#ifndef CW_OSMESA_LIBRARY
#error "CW_OSMESA_LIBRARY (the path of libOSMesa) must be defined by the build"
#endif

namespace cellwright::twin {

namespace {
constexpr int kMaxSide = 4096;
constexpr int kMaxGeoms = 4000;  // visual geoms per frame: the cell has a few hundred

// OSMesa's entry points. The library is loaded when the first Renderer is made, not with the program (render.hpp):
// it brings Mesa's llvmpipe, libLLVM and a dozen more libraries, whose loading cost every process about 0.1 s of CPU.
struct OsMesa {
  decltype(&OSMesaCreateContextExt) create = nullptr;
  decltype(&OSMesaMakeCurrent) make_current = nullptr;
  decltype(&OSMesaDestroyContext) destroy = nullptr;
};

const OsMesa& osmesa() {
  // Loaded once and kept for the life of the process. RTLD_GLOBAL: MuJoCo looks its OpenGL functions up in the
  // process (mjr_makeContext), as when the program linked OSMesa. A failure throws, and the next call tries again.
  static const OsMesa api = [] {
    void* lib = dlopen(CW_OSMESA_LIBRARY, RTLD_NOW | RTLD_GLOBAL);
    if (lib == nullptr) {
      const char* e = dlerror();
      throw std::runtime_error(
          fmt::format("cannot load OSMesa ({}): {}", CW_OSMESA_LIBRARY, e != nullptr ? e : "unknown reason"));
    }
    OsMesa out;
    out.create = reinterpret_cast<decltype(out.create)>(dlsym(lib, "OSMesaCreateContextExt"));
    out.make_current = reinterpret_cast<decltype(out.make_current)>(dlsym(lib, "OSMesaMakeCurrent"));
    out.destroy = reinterpret_cast<decltype(out.destroy)>(dlsym(lib, "OSMesaDestroyContext"));
    if (out.create == nullptr || out.make_current == nullptr || out.destroy == nullptr) {
      throw std::runtime_error(fmt::format("OSMesa ({}) lacks its context functions", CW_OSMESA_LIBRARY));
    }
    return out;
  }();
  return api;
}
}  // namespace

struct Renderer::Impl {
  OSMesaContext gl = nullptr;
  std::vector<unsigned char> framebuffer;  // OSMesa's window buffer; MuJoCo draws into its own offscreen buffer
  mjvScene scene{};
  mjrContext context{};
  mjvOption option{};
  std::vector<unsigned char> rgb;
  bool scene_made = false, context_made = false;

  ~Impl() {
    if (gl != nullptr) osmesa().make_current(gl, framebuffer.data(), GL_UNSIGNED_BYTE, 1, 1);
    if (context_made) mjr_freeContext(&context);
    if (scene_made) mjv_freeScene(&scene);
    if (gl != nullptr) osmesa().destroy(gl);
  }
};

Renderer::Renderer(const mjModel* model, int max_width, int max_height)
    : impl_(std::make_unique<Impl>()),
      model_(model),
      max_width_(max_width),
      max_height_(max_height),
      owner_(std::this_thread::get_id()) {
  CW_CHECK(model != nullptr, "Renderer needs a model");
  CW_CHECK(max_width > 0 && max_height > 0 && max_width <= kMaxSide && max_height <= kMaxSide,
           "renderer size {}x{} outside 1..{}", max_width, max_height, kMaxSide);
  Impl& r = *impl_;
  r.gl = osmesa().create(OSMESA_RGBA, 24, 8, 0, nullptr);
  if (r.gl == nullptr) throw std::runtime_error("OSMesa could not create an OpenGL context");
  r.framebuffer.resize(4);
  if (!osmesa().make_current(r.gl, r.framebuffer.data(), GL_UNSIGNED_BYTE, 1, 1)) {
    throw std::runtime_error("OSMesa could not make its OpenGL context current");
  }
  mjv_defaultOption(&r.option);
  mjv_defaultScene(&r.scene);
  mjv_makeScene(model, &r.scene, kMaxGeoms);
  r.scene_made = true;
  mjr_defaultContext(&r.context);
  // MuJoCo sizes its offscreen buffer from the model's visual settings; a copy of the model's header with the size
  // we need leaves the caller's model untouched (mjr_makeContext only reads the model).
  mjModel sized = *model;
  sized.vis.global.offwidth = max_width;
  sized.vis.global.offheight = max_height;
  mjr_makeContext(&sized, &r.context, mjFONTSCALE_100);
  r.context_made = true;
  mjr_setBuffer(mjFB_OFFSCREEN, &r.context);
  if (r.context.currentBuffer != mjFB_OFFSCREEN) {
    throw std::runtime_error("MuJoCo cannot render offscreen with this OpenGL (OSMesa) context");
  }
  if (r.context.offWidth < max_width || r.context.offHeight < max_height) {
    throw std::runtime_error(fmt::format("MuJoCo's offscreen buffer is {}x{}, smaller than the {}x{} asked for",
                                         r.context.offWidth, r.context.offHeight, max_width, max_height));
  }
}

Renderer::~Renderer() = default;

cv::Mat Renderer::render_camera(mjData* data, int camera_id, int width, int height, RenderQuality quality) {
  CW_CHECK(camera_id >= 0 && camera_id < model_->ncam, "camera id {} not in the model (it has {})", camera_id,
           model_->ncam);
  mjvCamera cam;
  mjv_defaultCamera(&cam);
  cam.type = mjCAMERA_FIXED;
  cam.fixedcamid = camera_id;
  return render(data, cam, width, height, quality);
}

namespace {

// The free camera of render_overview: it frames the bounding sphere of every visible geom but the floor plane, where
// they are now (the workpieces included, wherever they ended up), from in front and above: far enough back that the
// sphere fits both the vertical and the horizontal field of view.
mjvCamera framing_camera(const mjModel* model, const mjData* data, int width, int height) {
  Eigen::AlignedBox3d box;
  for (int g = 0; g < model->ngeom; ++g) {
    if (model->geom_type[g] == mjGEOM_PLANE || model->geom_group[g] > 2 || model->geom_rgba[4 * g + 3] == 0) {
      continue;
    }
    const Eigen::Vector3d c(data->geom_xpos[3 * g], data->geom_xpos[3 * g + 1], data->geom_xpos[3 * g + 2]);
    box.extend(c - Eigen::Vector3d::Constant(model->geom_rbound[g]));
    box.extend(c + Eigen::Vector3d::Constant(model->geom_rbound[g]));
  }
  if (box.isEmpty()) box = Eigen::AlignedBox3d(Eigen::Vector3d::Constant(-1), Eigen::Vector3d::Constant(1));
  // Bounding spheres of geoms overestimate; the box's half diagonal is a generous radius for the whole cell.
  const Eigen::Vector3d centre = box.center();
  const double radius = 0.5 * box.diagonal().norm();
  const double half_fovy = 0.5 * model->vis.global.fovy * std::numbers::pi / 180.0;
  const double half_fovx = std::atan(std::tan(half_fovy) * width / height);
  mjvCamera cam;
  mjv_defaultCamera(&cam);
  cam.type = mjCAMERA_FREE;
  for (int i = 0; i < 3; ++i) cam.lookat[i] = centre[i];
  cam.distance = 0.65 * radius / std::sin(std::min(half_fovy, half_fovx));
  cam.azimuth = 60;
  cam.elevation = -30;
  return cam;
}

}  // namespace

cv::Mat Renderer::render_overview(mjData* data, int width, int height) {
  return render(data, overview_camera(data, width, height), width, height, RenderQuality::kFull);
}

mjvCamera Renderer::overview_camera(const mjData* data, int width, int height) const {
  CW_CHECK(data != nullptr, "render needs data");
  CW_CHECK(width >= 1 && height >= 1, "image size {}x{}", width, height);
  return framing_camera(model_, data, width, height);
}

vision::CameraModel overview_camera_model(const mjModel* model, const mjData* data, int width, int height) {
  CW_CHECK(model != nullptr && data != nullptr && width > 0 && height > 0, "overview_camera_model({}x{})", width,
           height);
  const mjvCamera cam = framing_camera(model, data, width, height);
  // MuJoCo's free camera (mjv_updateCamera): it looks along `forward` from `distance` behind `lookat`.
  const double az = cam.azimuth * std::numbers::pi / 180.0, el = cam.elevation * std::numbers::pi / 180.0;
  const Eigen::Vector3d forward(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
  const Eigen::Vector3d up(-std::sin(el) * std::cos(az), -std::sin(el) * std::sin(az), std::cos(el));
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = Eigen::Vector3d(cam.lookat[0], cam.lookat[1], cam.lookat[2]) - cam.distance * forward;
  pose.linear().col(0) = forward.cross(up);
  pose.linear().col(1) = up;
  pose.linear().col(2) = -forward;
  return vision::CameraModel(pose, model->vis.global.fovy * std::numbers::pi / 180.0, width, height);
}

cv::Mat Renderer::render(mjData* data, const mjvCamera& camera, int width, int height, RenderQuality quality) {
  CW_CHECK(std::this_thread::get_id() == owner_, "a Renderer is used on the thread that made it only");
  CW_CHECK(data != nullptr, "render needs data");
  CW_CHECK(width >= 1 && height >= 1 && width <= max_width_ && height <= max_height_,
           "image size {}x{} outside 1x1..{}x{}", width, height, max_width_, max_height_);
  Impl& r = *impl_;
  if (!osmesa().make_current(r.gl, r.framebuffer.data(), GL_UNSIGNED_BYTE, 1, 1)) {
    throw std::runtime_error("OSMesa could not make its OpenGL context current");
  }
  mjvCamera cam = camera;
  const mjrRect viewport{0, 0, width, height};
  mjv_updateScene(model_, data, &r.option, nullptr, &cam, mjCAT_ALL, &r.scene);
  // Colours the run changed (a processed part): state in mjData::userdata, painted over the shared model's.
  for (int slot = 0; slot + kColourSlot <= model_->nuserdata; slot += kColourSlot) {
    const mjtNum* c = data->userdata + slot;
    const int geom = static_cast<int>(c[0]) - 1;
    if (geom < 0) continue;
    for (int i = 0; i < r.scene.ngeom; ++i) {
      mjvGeom& g = r.scene.geoms[i];
      if (g.objtype != mjOBJ_GEOM || g.objid != geom) continue;
      for (int k = 0; k < 4; ++k) g.rgba[k] = static_cast<float>(c[1 + k]);
    }
  }
  // Shadows cost a depth pass per shadow-casting light, reflections a mirrored pass of the scene.
  const mjtByte full = quality == RenderQuality::kFull ? 1 : 0;
  for (int flag : {mjRND_SHADOW, mjRND_REFLECTION, mjRND_SKYBOX}) r.scene.flags[flag] = full;
  mjr_setBuffer(mjFB_OFFSCREEN, &r.context);
  mjr_render(viewport, &r.scene, &r.context);
  r.rgb.resize(static_cast<std::size_t>(3) * static_cast<std::size_t>(width) * static_cast<std::size_t>(height));
  mjr_readPixels(r.rgb.data(), nullptr, viewport, &r.context);
  const int gl_error = mjr_getError();
  if (gl_error != 0) throw std::runtime_error(fmt::format("OpenGL error {} while rendering", gl_error));
  // OpenGL's rows run bottom to top; images run top to bottom.
  const cv::Mat rgb(height, width, CV_8UC3, r.rgb.data());
  cv::Mat bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  cv::flip(bgr, bgr, 0);
  return bgr;
}

vision::CameraModel camera_model(const mjModel* model, const mjData* data, int camera_id, int width, int height) {
  CW_CHECK(model != nullptr && data != nullptr, "camera_model needs a model and data");
  CW_CHECK(camera_id >= 0 && camera_id < model->ncam, "camera id {} not in the model (it has {})", camera_id,
           model->ncam);
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  const mjtNum* p = data->cam_xpos + 3 * camera_id;
  const mjtNum* r = data->cam_xmat + 9 * camera_id;
  pose.translation() = Eigen::Vector3d(p[0], p[1], p[2]);
  pose.linear() = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(r);
  return vision::CameraModel(pose, model->cam_fovy[camera_id] * std::numbers::pi / 180.0, width, height);
}

cv::Mat render_view(Scene& scene, std::string_view camera, int width, int height) {
  const std::string where = scene.cell().source.string();
  if (width < 1 || height < 1 || width > kMaxSide || height > kMaxSide) {
    throw InputError({where, 0, 0}, fmt::format("image size {}x{} is not within 1x1..{}x{} pixels", width, height,
                                                kMaxSide, kMaxSide));
  }
  int id = -1;
  if (camera != kOverviewCamera) {
    id = scene.camera_id(camera);
    if (id < 0) {
      std::string names(kOverviewCamera);
      for (const auto& c : scene.cell().cameras) names += ", " + c.name;
      throw InputError({where, 0, 0}, fmt::format("the cell has no camera '{}' (cameras: {})", camera, names));
    }
  }
  Renderer renderer(scene.model(), width, height);
  return id < 0 ? renderer.render_overview(scene.data(), width, height)
                : renderer.render_camera(scene.data(), id, width, height);
}

}  // namespace cellwright::twin
