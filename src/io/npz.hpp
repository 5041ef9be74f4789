// NumPy arrays: .npy files and .npz archives (a zip of .npy files), as DGP
// and other Python-made data sets store point clouds. Read with libzip (the
// archive and its deflate) and a header parser for the .npy format
// (numpy.lib.format, versions 1-3). Numbers only: float32/64 and
// (u)int8..64, little- or big-endian, C or Fortran order, 1 or 2 dimensions.
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "io/error.hpp"

namespace scenecal::io {

struct NpyArray {
  std::size_t rows = 0;  // shape[0]
  std::size_t cols = 1;  // shape[1], 1 for a 1-D array
  std::vector<double> values;  // row-major, rows x cols, converted to double

  double At(std::size_t row, std::size_t col) const { return values[row * cols + col]; }
};

// Parses the bytes of one .npy file; InputError naming `name` and the header
// field (or the data size) on anything malformed or unsupported. The array is
// allocated only after its size was checked against the bytes present.
NpyArray ParseNpy(const std::string& bytes, const std::string& name);

// Reads the array `member` ("data" or "data.npy"; empty: the archive's only
// member, or else its "data") of a .npz archive held in memory; `name` is used in messages.
// Members larger than max_member_bytes uncompressed are refused (a zip's
// sizes are checked before anything is inflated).
NpyArray ParseNpz(const std::string& archive_bytes, const std::string& name, const std::string& member,
                  std::size_t max_member_bytes = std::size_t{1} << 30);

// As ParseNpz, from a file (at most 2 GiB).
NpyArray ReadNpz(const std::filesystem::path& path, const std::string& member);

}  // namespace scenecal::io
