// Reader for PCD v0.7 point clouds (the Point Cloud Library's file format).
//
// A focused reader rather than PCL: PCL is the well-kept library for this, but
// on Debian it drags in VTK, Qt and Boost, an unreasonable footprint for
// reading x, y, z and intensity. Supported: DATA ascii | binary |
// binary_compressed (LZF, field-major), any field sizes and types (F 4/8,
// U/I 1/2/4/8), COUNT > 1 (the first element is used for named fields).
// Every header value is checked against the file's actual size before
// anything is allocated from it.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "core/rig.hpp"
#include "io/error.hpp"

namespace scenecal::io {

struct PcdCloud {
  std::size_t width = 0;
  std::size_t height = 0;
  std::string data_encoding;             // ascii | binary | binary_compressed
  std::vector<std::string> field_names;  // as in FIELDS
  // x, y, z (as stored, usually metres) and intensity (0 when the file has no
  // intensity field); non-finite points are kept, as the file has them.
  std::vector<LidarPoint> points;
  bool has_intensity = false;  // a field named intensity, reflectance or i
  // Per-point time from a field named timestamp, time or t (the file's unit);
  // empty when absent.
  std::vector<double> timestamps;
};

// Throws InputError naming the file and the header key or the data problem.
PcdCloud ReadPcd(const std::filesystem::path& path);
// Same, from bytes in memory; `name` is used in messages.
PcdCloud ParsePcd(const std::string& bytes, const std::string& name);

}  // namespace scenecal::io
