// PNG files of images (png.hpp).
#include "cellwright/vision/png.hpp"

#include <png.h>

#include <fmt/format.h>

#include <stdexcept>
#include <string>
#include <string_view>
#include <system_error>

#include "cellwright/common/error.hpp"
#include "cellwright/common/files.hpp"

namespace cellwright::vision {

std::vector<unsigned char> encode_png(const cv::Mat& image) {
  CW_CHECK(!image.empty() && image.type() == CV_8UC3, "encode_png needs an 8-bit, 3-channel image");
  png_image png{};
  png.version = PNG_IMAGE_VERSION;
  png.width = static_cast<png_uint_32>(image.cols);
  png.height = static_cast<png_uint_32>(image.rows);
  png.format = PNG_FORMAT_BGR;
  const auto stride = static_cast<png_int_32>(image.step / image.elemSize1());
  // First the size, then the bytes (libpng's simplified API).
  png_alloc_size_t size = 0;
  std::vector<unsigned char> out;
  if (png_image_write_to_memory(&png, nullptr, &size, 0, image.data, stride, nullptr) != 0) {
    out.resize(size);
    if (png_image_write_to_memory(&png, out.data(), &size, 0, image.data, stride, nullptr) != 0) {
      out.resize(size);
      return out;
    }
  }
  const std::string why = png.message;
  png_image_free(&png);
  throw std::runtime_error(fmt::format("the PNG encoder failed: {}", why));
}

void write_png(const cv::Mat& image, const std::filesystem::path& path) {
  CW_CHECK(!image.empty() && image.type() == CV_8UC3, "write_png needs an 8-bit, 3-channel image");
  const std::filesystem::path dir = path.has_parent_path() ? path.parent_path() : std::filesystem::path(".");
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec)) {
    throw InputError({path.string(), 0, 0},
                     fmt::format("cannot write the image: directory '{}' does not exist", dir.string()));
  }
  std::vector<unsigned char> bytes;
  try {
    bytes = encode_png(image);
  } catch (const std::runtime_error& e) {
    throw InputError({path.string(), 0, 0}, fmt::format("cannot write the image: {}", e.what()));
  }
  write_file_atomically(path, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
}

}  // namespace cellwright::vision
