// PNG files of images (the camera's frames, the reports' charts, the cell's snapshots), written with libpng.
//
// Thread safety: re-entrant functions; any thread may call them.
#pragma once

#include <opencv2/core.hpp>

#include <filesystem>
#include <vector>

namespace cellwright::vision {

// An 8-bit, 3-channel (BGR) image encoded as PNG bytes, with libpng: not OpenCV's image codecs, whose library loads
// GDAL, GDCM, Poppler and some hundred others into every process that links it (about 40 MB of a run's resident
// memory once an image is written; docs/simulation.md, "Memory"). Throws std::runtime_error with libpng's message if
// the encoder fails.
std::vector<unsigned char> encode_png(const cv::Mat& image);

// Writes an image as a PNG file atomically: to a temporary file in the same directory, then renamed over `path`, so
// that readers never see half a file. Throws InputError naming the path if the directory does not exist or the file
// cannot be written.
void write_png(const cv::Mat& image, const std::filesystem::path& path);

}  // namespace cellwright::vision
