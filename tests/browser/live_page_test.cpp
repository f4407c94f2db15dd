// The live view's 3D page in a real browser (docs/live-view.md): `twin serve scenes/exchange.yaml` as a user starts
// it, headless Chromium (software WebGL: SwiftShader) driven over the DevTools protocol (support/cdp_client.hpp).
// The page loads, draws the robots from their URDFs, and its picture from the cell's overhead camera shows the robots
// where MuJoCo's offscreen picture of the same state from the same camera shows them; clicking "step" makes the
// firings on the page rise. Skipped only when chromium is not installed (tools/bootstrap.sh test installs it).
//
// The comparison, robust to two renderers that light and shade differently: in each renderer the robots' silhouette
// is where the picture changes when the robots are hidden (three.js: the page's showRobots(false); MuJoCo: the
// robots' geoms moved to a hidden geom group), and the two silhouettes must overlap (IoU) and have close centroids.
// The same comparison with the page's view shifted by 15 cm must fail it (the test shows that it can fail).
#include <gtest/gtest.h>
#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <thread>

#include "cellwright/models/cell.hpp"
#include "cellwright/twin/render.hpp"
#include "cellwright/twin/scene.hpp"
#include "support/cdp_client.hpp"
#include "support/ws_viewer.hpp"
#include "tools/twin_cli.hpp"

namespace cellwright::testing {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using nlohmann::json;

const std::string kBanner = "serving the live view on http://127.0.0.1:";

std::optional<fs::path> find_chromium() {
  const char* path = std::getenv("PATH");
  std::string dirs = path ? path : "/usr/bin";
  for (std::size_t start = 0; start <= dirs.size();) {
    const std::size_t end = std::min(dirs.find(':', start), dirs.size());
    const fs::path exe = fs::path(dirs.substr(start, end - start)) / "chromium";
    if (::access(exe.c_str(), X_OK) == 0) return exe;
    start = end + 1;
  }
  return std::nullopt;
}

// Headless Chromium with a DevTools endpoint on a free port, its profile in a scratch directory; killed (by its pid)
// and reaped at the end.
class Chromium {
 public:
  Chromium(const fs::path& exe, const fs::path& scratch) : scratch_(scratch) {
    fs::create_directories(scratch);
    const fs::path err = scratch / "stderr";
    pid_ = ::fork();
    if (pid_ == 0) {
      const int fd = ::open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      ::dup2(fd, STDERR_FILENO);
      ::dup2(fd, STDOUT_FILENO);
      const std::string profile = "--user-data-dir=" + (scratch / "profile").string();
      // SwiftShader: WebGL in software, no GPU or display (this Chromium refuses it without the "unsafe" flag).
      ::execl(exe.c_str(), exe.c_str(), "--headless=new", "--no-sandbox", "--use-angle=swiftshader",
              "--enable-unsafe-swiftshader", "--remote-debugging-port=0", "--remote-debugging-address=127.0.0.1",
              "--window-size=640,480", "--hide-scrollbars", "--no-first-run", "--disable-extensions",
              profile.c_str(), "about:blank", static_cast<char*>(nullptr));
      ::_exit(127);
    }
    // "DevTools listening on ws://127.0.0.1:PORT/devtools/browser/ID" on its stderr.
    const auto until = std::chrono::steady_clock::now() + 15s;
    while (std::chrono::steady_clock::now() < until) {
      const std::string text = slurp(err);
      const auto at = text.find("DevTools listening on ");
      if (at != std::string::npos && text.find('\n', at) != std::string::npos) {
        const std::size_t from = at + 22;
        url_ = text.substr(from, text.find('\n', at) - from);
        return;
      }
      std::this_thread::sleep_for(50ms);  // polling a file another process writes: nothing to wait on
    }
  }
  ~Chromium() {
    if (pid_ > 0) {
      ::kill(pid_, SIGTERM);
      int raw = 0;
      ::waitpid(pid_, &raw, 0);
    }
  }
  Chromium(const Chromium&) = delete;
  Chromium& operator=(const Chromium&) = delete;
  const std::string& url() const { return url_; }
  std::string log() const { return slurp(scratch_ / "stderr"); }

 private:
  fs::path scratch_;
  pid_t pid_ = -1;
  std::string url_;
};

std::string base64_decode(const std::string& in) {
  auto value = [](char c) -> int {
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    if (c == '+') return 62;
    if (c == '/') return 63;
    return -1;
  };
  std::string out;
  int bits = 0, acc = 0;
  for (char c : in) {
    const int v = value(c);
    if (v < 0) continue;
    acc = (acc << 6) | v;
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      out.push_back(static_cast<char>((acc >> bits) & 0xff));
    }
  }
  return out;
}

// A page of the browser: a target attached with a session of its own.
class Page {
 public:
  Page(CdpClient& cdp, const std::string& url) : cdp_(cdp) {
    const json t = cdp.call("Target.createTarget", {{"url", url}});
    EXPECT_FALSE(t.contains("error")) << t.dump();
    const json a = cdp.call("Target.attachToTarget", {{"targetId", t.value("targetId", "")}, {"flatten", true}});
    session_ = a.value("sessionId", "");
    EXPECT_FALSE(session_.empty()) << a.dump();
    call("Emulation.setDeviceMetricsOverride",
         {{"width", 640}, {"height", 480}, {"deviceScaleFactor", 1}, {"mobile", false}});
  }
  json call(const std::string& method, const json& params) { return cdp_.call(method, params, session_); }
  // The value of a JavaScript expression (awaited if a promise), or null JSON.
  json eval(const std::string& expression) {
    const json r = call("Runtime.evaluate", {{"expression", expression}, {"returnByValue", true}, {"awaitPromise", true}});
    return r.contains("result") ? r["result"].value("value", json()) : json();
  }
  // window.cellwright (the page's status), waiting up to `timeout` until `done` accepts it; the last one seen.
  json wait_status(const std::function<bool(const json&)>& done, std::chrono::milliseconds timeout) {
    const auto until = std::chrono::steady_clock::now() + timeout;
    json s;
    while (std::chrono::steady_clock::now() < until) {
      const json v = eval("JSON.stringify(window.cellwright || null)");
      s = v.is_string() ? json::parse(v.get<std::string>(), nullptr, false) : json();
      if (s.is_object() && done(s)) return s;
      // Polling the page's state over the protocol: the page has no way to call the test back.
      std::this_thread::sleep_for(100ms);
    }
    return s;
  }
  // The page as it is drawn now (two animation frames after the last change), 640 x 480 BGR.
  cv::Mat screenshot() {
    eval("new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))");
    const json r = call("Page.captureScreenshot",
                        {{"format", "png"}, {"clip", {{"x", 0}, {"y", 0}, {"width", 640}, {"height", 480}, {"scale", 1}}}});
    const std::string png = base64_decode(r.value("data", ""));
    return cv::imdecode(std::vector<uchar>(png.begin(), png.end()), cv::IMREAD_COLOR);
  }
  // A mouse click at the middle of the element with this id, as a user's.
  bool click(const std::string& id) {
    // Scrolled into view first (a button low in the side panel may be below the window), then clicked where it is,
    // and only if that point is the button (nothing over it): a click that cannot land is a failure, not a miss.
    const json box = eval("(() => { const e = document.getElementById('" + id +
                          "'); e.scrollIntoView({block: 'center'}); const r = e.getBoundingClientRect(); "
                          "const x = r.x + r.width / 2, y = r.y + r.height / 2; "
                          "return document.elementFromPoint(x, y) === e ? [x, y] : null; })()");
    if (!box.is_array()) return false;
    for (const char* type : {"mousePressed", "mouseReleased"}) {
      call("Input.dispatchMouseEvent",
           {{"type", type}, {"x", box[0]}, {"y", box[1]}, {"button", "left"}, {"clickCount", 1}});
    }
    return true;
  }

 private:
  CdpClient& cdp_;
  std::string session_;
};

// Where two pictures of one renderer differ (any channel by more than 8 of 255: a renderer draws the same scene the
// same way twice, and a robot's light colour can be close to the floor's behind it): the robots' silhouette.
cv::Mat changed(const cv::Mat& a, const cv::Mat& b) {
  cv::Mat d;
  cv::absdiff(a, b, d);
  std::vector<cv::Mat> ch;
  cv::split(d, ch);
  cv::Mat m = cv::max(cv::max(ch[0], ch[1]), ch[2]);
  return m > 8;
}

double iou(const cv::Mat& a, const cv::Mat& b) {
  const double inter = cv::countNonZero(a & b), uni = cv::countNonZero(a | b);
  return uni > 0 ? inter / uni : 0;
}

cv::Point2d centroid(const cv::Mat& mask) {
  double n = 0, sx = 0, sy = 0;
  for (int y = 0; y < mask.rows; ++y) {
    for (int x = 0; x < mask.cols; ++x) {
      if (mask.at<uchar>(y, x)) {
        n += 1;
        sx += x;
        sy += y;
      }
    }
  }
  return n > 0 ? cv::Point2d(sx / n, sy / n) : cv::Point2d(-1e6, -1e6);
}

// MuJoCo's pictures of the exchange cell from `camera`, with the robots at the frame's joints: with the robots, and
// with their geoms in group 5 (not drawn).
std::pair<cv::Mat, cv::Mat> mujoco_pictures(const json& frame, const std::string& camera, int w, int h) {
  const models::CellDescription cell = models::load_cell(source_path("scenes/cell.yaml"));
  twin::Scene scene = twin::build_scene(cell);
  mjModel* m = const_cast<mjModel*>(scene.model());
  mjData* d = scene.data();
  for (const json& r : frame["robots"]) {
    const twin::RobotIds* ids = scene.find_robot(r["name"].get<std::string>());
    if (!ids) continue;
    for (std::size_t i = 0; i < ids->qpos_adr.size() && i < r["joints"].size(); ++i) d->qpos[ids->qpos_adr[i]] = r["joints"][i];
    for (int adr : ids->finger_qpos_adr) {
      if (adr >= 0) d->qpos[adr] = r.value("fingers", 0.0) / 2;
    }
  }
  mj_forward(m, d);
  twin::Renderer renderer(m, w, h);
  const int cam = scene.camera_id(camera);
  cv::Mat with = renderer.render_camera(d, cam, w, h, twin::RenderQuality::kVision);
  std::vector<bool> robot(static_cast<std::size_t>(m->nbody), false);
  for (const twin::RobotIds& r : scene.robots()) {
    for (int b = 1; b < m->nbody; ++b) {
      if (m->body_rootid[b] == m->body_rootid[r.base_body]) robot[static_cast<std::size_t>(b)] = true;
    }
  }
  for (int g = 0; g < m->ngeom; ++g) {
    if (robot[static_cast<std::size_t>(m->geom_bodyid[g])]) m->geom_group[g] = 5;
  }
  cv::Mat without = renderer.render_camera(d, cam, w, h, twin::RenderQuality::kVision);
  return {with, without};
}

class LivePage : public ::testing::Test {
 protected:
  void SetUp() override {
    chromium_exe_ = find_chromium();
    if (!chromium_exe_) GTEST_SKIP() << "chromium is not installed (apt-get install chromium; tools/bootstrap.sh test does)";
    scratch_ = fs::temp_directory_path() / ("cw-live-page-" + std::to_string(::getpid()));
    fs::create_directories(scratch_);
    twin_ = std::make_unique<BackgroundTwin>(std::vector<std::string>{"serve", scenario(), "--port", "0"});
    ASSERT_TRUE(twin_->wait_for("(Ctrl-C stops)", 60s)) << twin_->output();
    const auto at = twin_->output().find(kBanner);
    ASSERT_NE(at, std::string::npos) << twin_->output();
    port_ = static_cast<std::uint16_t>(std::stoi(twin_->output().substr(at + kBanner.size())));
    chromium_ = std::make_unique<Chromium>(*chromium_exe_, scratch_);
    ASSERT_FALSE(chromium_->url().empty()) << "no DevTools endpoint from chromium:\n" << chromium_->log();
    cdp_ = std::make_unique<CdpClient>(chromium_->url());
    ASSERT_TRUE(cdp_->connected()) << chromium_->url();
  }
  void TearDown() override {
    cdp_.reset();
    chromium_.reset();
    twin_.reset();
    if (!scratch_.empty()) fs::remove_all(scratch_);
  }
  std::string url(const std::string& query = "") const {
    return "http://127.0.0.1:" + std::to_string(port_) + "/" + query;
  }
  // The scenario served: the exchange scenario of the source tree, unless a test serves a copy.
  virtual std::string scenario() { return source_path("scenes/exchange.yaml"); }
  static bool ready(const json& s) { return s.is_object() && s.value("ready", false) && s.value("robots", 0) == 2 && s.value("links", 0) > 2; }

  std::optional<fs::path> chromium_exe_;
  fs::path scratch_;
  std::unique_ptr<BackgroundTwin> twin_;
  std::uint16_t port_ = 0;
  std::unique_ptr<Chromium> chromium_;
  std::unique_ptr<CdpClient> cdp_;
};

// The robots' silhouettes in the browser's picture from `query`'s view: with and without the robots.
cv::Mat browser_silhouette(Page& page) {
  const cv::Mat with = page.screenshot();
  page.eval("window.cellwright.showRobots(false)");
  const cv::Mat without = page.screenshot();
  page.eval("window.cellwright.showRobots(true)");
  if (with.empty() || without.empty()) return {};
  return changed(with, without);
}

TEST_F(LivePage, TheRobotsAreDrawnWhereMuJoCoDrawsThemFromTheOverheadCamera) {
  WsViewer viewer(port_);
  const json frame = viewer.wait_for("frame");
  ASSERT_TRUE(frame.is_object());
  ASSERT_EQ(frame["firings"], 0);

  Page page(*cdp_, url("?view=camera:overhead"));
  const json s = page.wait_status(ready, 15s);
  ASSERT_TRUE(ready(s)) << "the page did not draw both robots: " << s.dump() << "\n" << chromium_->log();
  EXPECT_EQ(s["firings"], 0);
  const cv::Mat browser = browser_silhouette(page);
  ASSERT_FALSE(browser.empty());
  Page shifted(*cdp_, url("?view=camera:overhead&shift=0.15,0,0"));
  ASSERT_TRUE(ready(shifted.wait_status(ready, 15s)));
  const cv::Mat moved = browser_silhouette(shifted);

  const auto [with, without] = mujoco_pictures(frame, "overhead", 640, 480);
  const cv::Mat mujoco = changed(with, without);
  // Both robots are a good part of the picture from 2.6 m (a few percent of its pixels each).
  EXPECT_GT(cv::countNonZero(mujoco), 640 * 480 / 50);
  EXPECT_GT(cv::countNonZero(browser), 640 * 480 / 50);
  const double same = iou(browser, mujoco), off = iou(moved, mujoco);
  const double dist = cv::norm(centroid(browser) - centroid(mujoco));
  const double dist_off = cv::norm(centroid(moved) - centroid(mujoco));
  EXPECT_GT(same, 0.75) << "the robots' silhouettes overlap too little";
  EXPECT_LT(dist, 10) << "the robots' silhouettes' centroids are too far apart (pixels)";
  // The check can fail: 15 cm off (about 20 pixels here) fails it.
  EXPECT_LT(off, 0.75);
  EXPECT_GT(dist_off, 10);
  RecordProperty("iou", std::to_string(same));
  std::printf("robots' silhouettes: IoU %.3f, centroids %.1f px apart; view shifted 15 cm: IoU %.3f, %.1f px\n", same,
              dist, off, dist_off);
  if (HasFailure() || std::getenv("CW_KEEP_PICTURES")) {
    cv::imwrite((fs::temp_directory_path() / "cw-live-page-browser.png").string(), browser);
    cv::imwrite((fs::temp_directory_path() / "cw-live-page-mujoco.png").string(), mujoco);
  }
}

TEST_F(LivePage, ClickingStepMakesTheFiringsRise) {
  Page page(*cdp_, url());
  json s = page.wait_status(ready, 15s);
  ASSERT_TRUE(ready(s)) << s.dump() << "\n" << chromium_->log();
  ASSERT_EQ(s["firings"], 0);
  ASSERT_TRUE(page.click("step"));
  s = page.wait_status([](const json& st) { return st.value("firings", 0) >= 1; }, 10s);
  ASSERT_TRUE(s.is_object());
  // One step runs to the next firing: the transitions enabled together fire in it (3 here).
  const int firings = s.value("firings", 0);
  EXPECT_GE(firings, 1) << s.dump();
  EXPECT_EQ(s["state"], "paused");
  const json text = page.eval("document.getElementById('state').textContent");
  EXPECT_NE(text.get<std::string>().find(", " + std::to_string(firings) + " firings"), std::string::npos) << text;
  EXPECT_TRUE(s["errors"].empty()) << s.dump();
}

// Teaching from the page: jog the PUMA's first joint, save the pose as a location, and the cell description on disk
// (a copy of scenes/ and the robots' URDFs in a scratch directory) has it. Needs the server's side of teaching
// (PROTOCOL29: "teach", "save_location"); skipped, saying so, while the server refuses "teach".
class LivePageTeach : public LivePage {
 protected:
  std::string scenario() override {
    const fs::path copy = scratch_ / "cell";
    fs::create_directories(copy / "scenes");
    fs::create_directories(copy / "models");
    for (const char* f : {"exchange.yaml", "cell.yaml", "exchange.task"}) {
      fs::copy_file(source_path(std::string("scenes/") + f), copy / "scenes" / f);
    }
    fs::copy(source_path("models/urdf"), copy / "models" / "urdf", fs::copy_options::recursive);
    cell_yaml_ = copy / "scenes" / "cell.yaml";
    return (copy / "scenes" / "exchange.yaml").string();
  }
  fs::path cell_yaml_;
};

TEST_F(LivePageTeach, JoggingAndSavingALocationChangesTheCellFileOnDisk) {
  {
    WsViewer probe(port_);
    ASSERT_TRUE(probe.wait_for("frame").is_object());
    probe.send(R"({"type":"teach","robot":"puma","action":"end"})");
    const json answer = probe.wait_for([](const json& m) { return m.value("type", "") == "teach" || m.value("type", "") == "error"; });
    // The server teaches (ending a teach that never began is refused as such, not as an unknown message).
    ASSERT_EQ(answer.value("reason", "").find("unknown type"), std::string::npos) << answer.dump();
  }
  const std::string before = slurp(cell_yaml_);
  Page page(*cdp_, url());
  ASSERT_TRUE(ready(page.wait_status(ready, 15s)));
  ASSERT_TRUE(page.click("teach-begin"));
  json s = page.wait_status([](const json& st) { return st.contains("teach") && st["teach"].value("active", false); }, 10s);
  ASSERT_TRUE(s.contains("teach")) << s.dump();
  const double j0 = s["teach"]["joints"][0];
  ASSERT_TRUE(page.click("jog-0-plus"));  // + 5 degrees
  s = page.wait_status([&](const json& st) { return st["teach"]["joints"][0].get<double>() > j0 + 0.01; }, 10s);
  EXPECT_NEAR(s["teach"]["joints"][0].get<double>(), j0 + 5 * M_PI / 180, 1e-6) << s.dump();
  page.eval("document.getElementById('teach-name').value = 'taught_in_browser'");
  ASSERT_TRUE(page.click("teach-save"));
  s = page.wait_status([](const json& st) { return st.contains("saved"); }, 10s);
  ASSERT_TRUE(s.contains("saved")) << s.dump() << "\ntwin serve said: " << twin_->output();
  EXPECT_EQ(s["saved"]["name"], "taught_in_browser");
  const std::string after = slurp(cell_yaml_);
  EXPECT_NE(after, before);
  EXPECT_NE(after.find("taught_in_browser"), std::string::npos) << after;
  // The file's own comments are kept.
  EXPECT_NE(after.find("# The workcell of the paper (Yasuda, section 2)"), std::string::npos);
}

}  // namespace
}  // namespace cellwright::testing
