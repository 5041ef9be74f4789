// A NumPy .npz archive (a zip of .npy files; DGP point clouds): io::ParseNpz,
// and the same bytes as a bare .npy file: io::ParseNpy.
#include <cmath>

#include "fuzz_common.hpp"
#include "io/npz.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace scenecal;
  const auto check = [](const io::NpyArray& array) {
    fuzz::Check(array.values.size() == array.rows * array.cols, "values fill the shape");
  };
  fuzz::RunParser(data, size, [&](const std::string& bytes) { check(io::ParseNpy(bytes, "data.npy")); });
  // A small member cap keeps an archive that claims gigabytes from being inflated.
  return fuzz::RunParser(data, size, [&](const std::string& bytes) {
    check(io::ParseNpz(bytes, "cloud.npz", "", std::size_t{16} << 20));
  });
}
