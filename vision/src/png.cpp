// PNG files of images (png.hpp).
#include "cellwright/vision/png.hpp"

#include <png.h>

#include <fmt/format.h>

#include <memory>

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
  // One pass of the encoder into a buffer of libpng's bound on the stream's size (PNG_IMAGE_PNG_SIZE_MAX): asking
  // for the size first would compress the image twice. Should the bound ever be short, libpng says how much it needs
  // and the second pass has that.
  png_alloc_size_t size = PNG_IMAGE_PNG_SIZE_MAX(png);
  for (int pass = 0; pass < 2; ++pass) {
    auto buffer = std::make_unique_for_overwrite<unsigned char[]>(size);
    const png_alloc_size_t room = size;
    if (png_image_write_to_memory(&png, buffer.get(), &size, 0, image.data, stride, nullptr) != 0) {
      return std::vector<unsigned char>(buffer.get(), buffer.get() + size);
    }
    if (size <= room) break;  // an error, not a short buffer
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
