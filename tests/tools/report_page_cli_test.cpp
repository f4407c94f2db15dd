// The report page of `twin run -o DIR` opened as a person opens it: in a browser (Debian's headless Chromium). A
// checker script is added to a copy of index.html; on the window's load event (which waits for every image) it writes
// into the DOM, for each <img>, whether the browser decoded it and whether every pixel of it was drawn (kChecker), and
// Chromium's --dump-dom prints the DOM after the load. Each picture must have decoded whole at the size of the PNG
// file it was made from; a copy with damaged pictures must show them broken (the check can fail).
// Skipped only when chromium is not installed (tools/bootstrap.sh test installs it, so CI runs this).
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>

#include "tools/twin_cli.hpp"

namespace {

namespace fs = std::filesystem;
using cellwright::testing::Outcome;
using cellwright::testing::shell_quote;
using cellwright::testing::slurp;
using cellwright::testing::source_path;
using cellwright::testing::TwinCli;
using ::testing::HasSubstr;

// Debian's chromium on the PATH, or nullopt.
std::optional<fs::path> find_chromium() {
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path != nullptr ? path : "/usr/bin:/bin");
  std::string dir;
  while (std::getline(dirs, dir, ':')) {
    const fs::path exe = fs::path(dir.empty() ? "." : dir) / "chromium";
    if (::access(exe.c_str(), X_OK) == 0) return exe;
  }
  return std::nullopt;
}

// Written into the page's DOM once the window has loaded (the load event waits for every image):
// "images <alt>=<state>;..." where the state is the picture's size "WxH" when the browser decoded all of it, "broken"
// when it could not decode it (not complete, or naturalWidth 0), "incomplete(N pixels not drawn)" when it decoded
// only part (a PNG cut short or damaged inside still has a size: the rows after the damage stay transparent, and our
// pictures are opaque RGB, so every drawn pixel has alpha 255). Pictures from data: URIs do not taint the canvas.
constexpr const char* kChecker = R"js(<script>
window.addEventListener("load", function () {
  var r = [];
  for (var k = 0; k < document.images.length; ++k) {
    var img = document.images[k], w = img.naturalWidth, h = img.naturalHeight, state;
    if (!img.complete || w === 0) {
      state = "broken";
    } else {
      var c = document.createElement("canvas");
      c.width = w;
      c.height = h;
      var g = c.getContext("2d");
      g.drawImage(img, 0, 0);
      var d = g.getImageData(0, 0, w, h).data, holes = 0;
      for (var p = 3; p < d.length; p += 4) if (d[p] !== 255) ++holes;
      state = holes ? "incomplete(" + holes + " pixels not drawn)" : w + "x" + h;
    }
    r.push(img.alt + "=" + state);
  }
  var pre = document.createElement("pre");
  pre.id = "cw-check";
  pre.textContent = "images " + r.join(";");
  document.body.appendChild(pre);
});
</script>
)js";

// A PNG file's size from its IHDR chunk, "WxH".
std::string png_size(const std::string& png) {
  if (png.size() < 24 || png.compare(1, 3, "PNG") != 0) return "not a PNG";
  auto be32 = [&](std::size_t at) {
    std::uint32_t v = 0;
    for (std::size_t i = 0; i < 4; ++i) v = (v << 8) | static_cast<unsigned char>(png[at + i]);
    return v;
  };
  return std::to_string(be32(16)) + "x" + std::to_string(be32(20));
}

// Opens `page` (with the checker added, as a copy beside it so that relative links resolve alike) in headless
// Chromium and returns what the checker wrote, or what went wrong.
std::string images_in_browser(const fs::path& chromium, const fs::path& page, const fs::path& scratch) {
  std::string html = slurp(page);
  const auto body_end = html.rfind("</body>");
  if (body_end == std::string::npos) return "no </body> in the page";
  html.insert(body_end, kChecker);
  const fs::path copy = page.parent_path() / ("checked-" + page.filename().string());
  std::ofstream(copy, std::ios::binary) << html;
  const fs::path dom = scratch / "dom.html", err = scratch / "chromium.err";
  // --no-sandbox: Chromium refuses to run as root with its sandbox (CI runs as root); the page is our own file.
  // A profile of its own in the scratch directory; `timeout` so that a browser that hangs fails the test.
  const std::string cmd = "timeout 120 " + shell_quote(chromium.string()) +
                          " --headless --no-sandbox --disable-gpu --disable-dev-shm-usage --no-first-run"
                          " --user-data-dir=" +
                          shell_quote((scratch / "profile").string()) + " --dump-dom " +
                          shell_quote("file://" + fs::absolute(copy).string()) + " >" + shell_quote(dom.string()) +
                          " 2>" + shell_quote(err.string()) + " </dev/null";
  const int status = std::system(cmd.c_str());
  const std::string out = slurp(dom);
  const std::string open = "<pre id=\"cw-check\">";
  const auto at = out.find(open);
  if (status != 0 || at == std::string::npos) {
    return "chromium exited with " + std::to_string(status) + ", no check in its DOM; stderr:\n" + slurp(err);
  }
  return out.substr(at + open.size(), out.find("</pre>", at) - at - open.size());
}

TEST(ReportPageCli, TheRunsPageRendersInABrowserWithItsPictures) {
  const std::optional<fs::path> chromium = find_chromium();
  if (!chromium) GTEST_SKIP() << "chromium is not installed (apt-get install chromium; tools/bootstrap.sh test does)";
  TwinCli cli("cw-report-page-cli");
  const fs::path out = cli.dir() / "out";
  const Outcome run =
      cli.run("run " + shell_quote(source_path("scenes/single.yaml")) + " --quiet -o " + shell_quote(out.string()));
  ASSERT_EQ(run.status, 0) << run.out << run.err;
  const fs::path page = out / "index.html";
  ASSERT_TRUE(fs::is_regular_file(page));
  const std::string html = slurp(page);
  EXPECT_THAT(html, HasSubstr("<div class=\"word\">OK</div>"));
  EXPECT_THAT(html, HasSubstr("<h1>single.yaml</h1>"));

  const std::string expected =
      "images Gantt chart=" + png_size(slurp(out / "gantt.png")) + ";final snapshot=" + png_size(slurp(out / "final.png"));
  EXPECT_EQ(images_in_browser(*chromium, page, cli.dir()), expected);

  // The check can fail: a copy whose chart has its PNG signature overwritten (its first 9 bytes, 12 base64
  // characters) and whose snapshot's data is cut after the first half.
  const std::string uri = "data:image/png;base64,";
  const auto gantt = html.find(uri), final = html.find(uri, gantt + 1);
  ASSERT_NE(final, std::string::npos);
  std::string broken = html;
  const auto final_data = final + uri.size(), final_end = broken.find('"', final_data);
  const auto half = (final_end - final_data) / 2 / 4 * 4;  // whole base64 quanta
  broken.erase(final_data + half, final_end - final_data - half);
  broken.replace(gantt + uri.size(), 12, "AAAAAAAAAAAA");
  const fs::path broken_page = out / "broken.html";
  std::ofstream(broken_page, std::ios::binary) << broken;
  EXPECT_THAT(images_in_browser(*chromium, broken_page, cli.dir()),
              ::testing::MatchesRegex("images Gantt chart=broken;final snapshot=incomplete\\([0-9]+ pixels not "
                                      "drawn\\)"));
}

}  // namespace
