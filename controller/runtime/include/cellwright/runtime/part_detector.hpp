// PartDetector: what the image-processing thread asks of a vision system. Given a camera picture and where the
// environment model expects the parts, it says which workpieces it sees, where, and how sure it is. The runtime knows
// only this interface; the cell's detector (twin/vision, on OpenCV) implements it, and tests supply doubles.
//
// Threads: detect() is called on the image-processing thread only, one call at a time; an implementation may keep
// state between calls (e.g. the last full result, for whoever draws it).
#pragma once

#include <Eigen/Geometry>

#include <any>
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "cellwright/runtime/plant.hpp"

namespace cellwright::runtime {

// Where the model expects a workpiece to be, to tell same-coloured parts apart.
struct Prediction {
  std::string workpiece;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
};

// A workpiece seen confidently in a picture.
struct Sighting {
  std::string workpiece;                                   // cell name
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  // its centre, world (yaw 0 when the shape has none)
  std::optional<double> yaw;                               // turn about world z, radians; none for a cylinder
  double confidence = 0;                                   // in [0, 1]
};

// What one picture showed.
struct Sightings {
  std::vector<Sighting> seen;         // in the cell's workpiece order
  std::vector<std::string> not_seen;  // the detector's workpieces it did not find, in the cell's order
  std::size_t rejected = 0;           // blobs it found and did not trust (partly hidden, merged, lifted)
  std::string frame_problem;          // non-empty when the picture could not be used at all (size, type)
  // The detector's own full result, for whoever wants to draw it (the cell's detector: vision::DetectionResult).
  std::any detail;
};

class PartDetector {
 public:
  virtual ~PartDetector() = default;

  // The workpieces it looks for (cell names, in the cell's order).
  virtual std::vector<std::string> workpieces() const = 0;

  // Finds the workpieces in `image`. Never throws on what the picture shows: a picture it cannot use gives
  // frame_problem and every workpiece not seen.
  virtual Sightings detect(const Image& image, const std::vector<Prediction>& predictions) const = 0;
};

}  // namespace cellwright::runtime
