// PNG files of images (vision/png.hpp).
#include "cellwright/vision/png.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include <filesystem>
#include <fstream>

#include "cellwright/common/error.hpp"

namespace cellwright::vision {
namespace {

using ::testing::HasSubstr;

TEST(WritePng, WritesAtomicallyAndReadsBack) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "cellwright_render_test";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  cv::Mat image(30, 40, CV_8UC3, cv::Scalar(10, 200, 30));
  image.at<cv::Vec3b>(5, 7) = cv::Vec3b(255, 0, 255);
  const std::filesystem::path out = dir / "snap.png";
  std::ofstream(out) << "an older file";
  write_png(image, out);
  const cv::Mat back = cv::imread(out.string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(back.empty());
  EXPECT_EQ(cv::norm(image, back, cv::NORM_INF), 0.0);
  // Only the PNG is left: no temporary file.
  int files = 0;
  for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(dir)) ++files;
  EXPECT_EQ(files, 1);
  try {
    write_png(image, dir / "missing" / "snap.png");
    FAIL() << "wrote into a missing directory";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("does not exist"));
  }
  std::filesystem::remove_all(dir);
}

TEST(EncodePng, DecodesToTheSamePixelsIncludingARegionOfALargerImage) {
  // Seeded noise (no run of equal bytes to hide a wrong stride or channel order), and a region whose rows are not
  // contiguous in memory.
  cv::Mat image(37, 53, CV_8UC3);
  cv::RNG rng(7);
  rng.fill(image, cv::RNG::UNIFORM, 0, 256);
  for (const cv::Mat& m : {image, cv::Mat(image(cv::Rect(3, 4, 21, 17)))}) {
    const std::vector<unsigned char> bytes = encode_png(m);
    ASSERT_GT(bytes.size(), 8u);
    const cv::Mat back = cv::imdecode(bytes, cv::IMREAD_COLOR);
    ASSERT_EQ(back.size(), m.size());
    EXPECT_EQ(cv::norm(m, back, cv::NORM_INF), 0.0);
  }
}

}  // namespace
}  // namespace cellwright::vision
