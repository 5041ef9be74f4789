#include "io/sensor_files.hpp"

#include <algorithm>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <system_error>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <zlib.h>

#include "io/yaml_fields.hpp"

namespace scenecal::io {

namespace fs = std::filesystem;
using detail::Fail;

static_assert(std::endian::native == std::endian::little,
              "scan files are little-endian float32; a big-endian host would need byte swapping");

namespace {

// Largest image or scan file read whole into memory (bytes); larger is refused
// as certainly not a frame of this format.
constexpr std::size_t kMaxDataFileBytes = std::size_t{1} << 30;

std::string Lowercase(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(), [](unsigned char c) { return std::tolower(c); });
  return text;
}

std::string ReadBinaryFile(const fs::path& path, std::size_t max_bytes) {
  return detail::ReadTextFile(path, max_bytes);  // same checks; the content is bytes either way
}

void WriteBinaryFile(const fs::path& path, const void* data, std::size_t size) {
  std::ofstream stream(path, std::ios::binary | std::ios::trunc);
  if (stream) stream.write(static_cast<const char*>(data), static_cast<std::streamsize>(size));
  stream.close();
  if (!stream) throw std::runtime_error("cannot write " + path.string());
}

bool IsImageExtension(const std::string& extension) {
  const std::string lower = Lowercase(extension);
  return lower == ".png" || lower == ".jpg" || lower == ".jpeg";
}

// The data files of one sensor's folder, sorted by time.
std::vector<SensorFile> ListSensorFiles(const fs::path& directory, bool images, const std::string& expected_files) {
  std::vector<SensorFile> files;
  for (const fs::directory_entry& file : fs::directory_iterator(directory)) {
    const fs::path& path = file.path();
    const std::string extension = path.extension().string();
    const bool good_extension = images ? IsImageExtension(extension) : extension == ".bin";
    if (!file.is_regular_file() || !good_extension) {
      Fail(path.string(), "file name", "'" + path.filename().string() + "' is not a data file of this folder",
           expected_files);
    }
    const std::optional<TimeUs> t_us = ParseTimestamp(path.stem().string());
    if (!t_us) Fail(path.string(), "file name", "'" + path.stem().string() + "' is not a timestamp", expected_files);
    files.push_back({*t_us, path});
  }
  std::sort(files.begin(), files.end(), [](const SensorFile& a, const SensorFile& b) {
    return a.t_us != b.t_us ? a.t_us < b.t_us : a.path < b.path;
  });
  for (std::size_t i = 1; i < files.size(); ++i) {
    if (files[i].t_us == files[i - 1].t_us) {
      Fail(files[i].path.string(), "file name",
           fmt::format("timestamp {} also used by {}", files[i].t_us, files[i - 1].path.filename().string()),
           "one file per timestamp");
    }
  }
  return files;
}

std::uint32_t BigEndian32(const unsigned char* bytes) {
  return (std::uint32_t{bytes[0]} << 24) | (std::uint32_t{bytes[1]} << 16) | (std::uint32_t{bytes[2]} << 8) |
         std::uint32_t{bytes[3]};
}

// (width, height) from a PNG IHDR or a JPEG SOF marker, without decoding; lets
// ReadImage reject a wrong size (or an absurd claimed size) before OpenCV
// allocates the image.
std::optional<std::pair<int, int>> ImageSizeFromHeader(const std::string& bytes) {
  const auto* data = reinterpret_cast<const unsigned char*>(bytes.data());
  const std::size_t size = bytes.size();
  static constexpr unsigned char kPngSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (size >= 24 && std::memcmp(data, kPngSignature, 8) == 0 && std::memcmp(data + 12, "IHDR", 4) == 0) {
    const std::uint32_t width = BigEndian32(data + 16);
    const std::uint32_t height = BigEndian32(data + 20);
    if (width == 0 || height == 0 || width > 1u << 30 || height > 1u << 30) return std::nullopt;
    return std::make_pair(static_cast<int>(width), static_cast<int>(height));
  }
  if (size >= 4 && data[0] == 0xFF && data[1] == 0xD8) {
    std::size_t pos = 2;
    while (pos + 4 <= size) {
      if (data[pos] != 0xFF) return std::nullopt;
      const unsigned char marker = data[pos + 1];
      if (marker == 0xFF) {  // fill byte
        ++pos;
        continue;
      }
      if (marker == 0xD8 || marker == 0x01 || (marker >= 0xD0 && marker <= 0xD7)) {  // no length
        pos += 2;
        continue;
      }
      const std::size_t length = (std::size_t{data[pos + 2]} << 8) | data[pos + 3];
      const bool start_of_frame =
          marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC;
      if (start_of_frame) {
        if (pos + 9 > size) return std::nullopt;
        const int height = (data[pos + 5] << 8) | data[pos + 6];
        const int width = (data[pos + 7] << 8) | data[pos + 8];
        if (width == 0 || height == 0) return std::nullopt;
        return std::make_pair(width, height);
      }
      if (marker == 0xD9 || marker == 0xDA || length < 2) return std::nullopt;  // no frame header before the data
      pos += 2 + length;
    }
  }
  return std::nullopt;
}

// Walks the PNG chunks checking lengths and CRCs. libpng prints its own
// "libpng error" lines to stderr on a corrupt file; checking first keeps the
// one clear message ours and catches truncation and bit flips before decoding.
std::optional<std::string> PngStructureProblem(const std::string& bytes) {
  const auto* data = reinterpret_cast<const unsigned char*>(bytes.data());
  std::size_t pos = 8;
  while (pos + 12 <= bytes.size()) {
    const std::size_t length = BigEndian32(data + pos);
    const std::string type(bytes.data() + pos + 4, 4);
    if (length > bytes.size() - pos - 12) {
      return fmt::format("chunk at byte {} claims {} bytes, past the end of the file (truncated or corrupt)", pos,
                         length);
    }
    const uLong crc = crc32(crc32(0L, Z_NULL, 0), data + pos + 4, static_cast<uInt>(length + 4));
    if (crc != BigEndian32(data + pos + 8 + length)) {
      return fmt::format("CRC error in the chunk at byte {} (corrupt)", pos);
    }
    if (type == "IEND") return std::nullopt;
    pos += 12 + length;
  }
  return std::string("no IEND chunk (truncated)");
}

}  // namespace

// ---- sensor folders ------------------------------------------------------------

std::optional<TimeUs> ParseTimestamp(const std::string& text) {
  TimeUs value = 0;
  if (text.empty() || text.front() == ' ' || text.back() == ' ') return std::nullopt;
  if (!detail::ParseWholeToken(text, &value)) return std::nullopt;
  return value;
}

std::map<std::string, std::vector<SensorFile>> detail::ListSensorFolders(const fs::path& root,
                                                                         const std::string& folder,
                                                                         const std::set<std::string>& sensors,
                                                                         bool images, const std::string& sensor_word) {
  std::map<std::string, std::vector<SensorFile>> listing;
  const fs::path directory = root / folder;
  const std::string expected_files = images ? "files named <t_us>.png, <t_us>.jpg or <t_us>.jpeg (int64 microseconds)"
                                            : "files named <t_us>.bin (int64 microseconds)";
  const std::string expected_folder =
      fmt::format("a folder {}/<{}>/ with at least one data file for every {} of rig.yaml", folder, sensor_word,
                  sensor_word);
  // Symlink loops, permissions and the like surface as filesystem errors
  // (ELOOP, EACCES): they are the dataset's fault, so they name the path.
  try {
    std::error_code error;
    if (!fs::exists(directory, error)) {
      Fail(directory.string(), folder + "/" + (sensors.empty() ? std::string() : *sensors.begin()), "missing",
           expected_folder);
    }
    if (!fs::is_directory(directory)) Fail(directory.string(), "folder", "not a directory", "a directory");
    for (const fs::directory_entry& entry : fs::directory_iterator(directory)) {
      const std::string name = entry.path().filename().string();
      if (!entry.is_directory()) {
        Fail(entry.path().string(), folder, "a stray file", "only one folder per " + sensor_word + " of rig.yaml");
      }
      if (sensors.count(name) == 0) {
        Fail(entry.path().string(), folder + "/" + name, "a folder for '" + name + "', which is not a " +
                 sensor_word + " of rig.yaml", "folders named after the " + sensor_word + "s in rig.yaml");
      }
      listing[name] = ListSensorFiles(entry.path(), images, expected_files);
    }
  } catch (const fs::filesystem_error& e) {
    const fs::path where = e.path1().empty() ? directory : e.path1();
    Fail(where.string(), folder, "cannot be listed (" + e.code().message() + ")", "a readable folder of data files");
  }
  for (const std::string& name : sensors) {
    const auto found = listing.find(name);
    if (found == listing.end() || found->second.empty()) {
      Fail((directory / name).string(), folder + "/" + name,
           found == listing.end() ? "missing" : "empty (no data file)", expected_folder);
    }
  }
  return listing;
}

std::vector<SensorFile> ListLidarScans(const fs::path& root, const std::string& lidar) {
  // The lidars folder may hold other lidars' folders: list them all, keep one.
  std::set<std::string> lidars;
  std::error_code error;
  for (const fs::directory_entry& entry : fs::directory_iterator(root / "lidars", error)) {
    lidars.insert(entry.path().filename().string());
  }
  lidars.insert(lidar);
  return detail::ListSensorFolders(root, "lidars", lidars, false, "lidar").at(lidar);
}

// ---- images --------------------------------------------------------------------------

std::optional<std::pair<int, int>> ImageFileSize(const fs::path& path) {
  std::ifstream stream(path, std::ios::binary);
  std::string head(64 * 1024, '\0');  // JPEG frame headers follow EXIF blocks, usually within 64 KiB
  stream.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<std::size_t>(stream.gcount()));
  return ImageSizeFromHeader(head);
}

bool ParseImageChannel(const std::string& name, ImageChannel* channel) {
  return ParseEnumName(kImageChannelNames, name, channel);
}

const char* ImageChannelName(ImageChannel channel) { return EnumName(kImageChannelNames, channel); }

GreyImage ReadImage(const SensorFile& file, const CameraModel& camera, ImageChannel channel) {
  const std::string name = file.path.string();
  const std::string bytes = ReadBinaryFile(file.path, kMaxDataFileBytes);
  const std::string expected_size = fmt::format("{} x {} pixels as in rig.yaml", camera.width, camera.height);
  const auto header_size = ImageSizeFromHeader(bytes);
  if (!header_size) Fail(name, "image", "not a readable PNG or JPEG header", "a PNG or JPEG image");
  if (header_size->first != camera.width || header_size->second != camera.height) {
    Fail(name, "image size", fmt::format("{} x {} pixels", header_size->first, header_size->second), expected_size);
  }
  if (bytes.size() >= 8 && bytes.compare(1, 3, "PNG") == 0) {
    if (const auto problem = PngStructureProblem(bytes)) Fail(name, "image", *problem, "a valid PNG image");
  }
  if (bytes.size() >= 2 && static_cast<unsigned char>(bytes[0]) == 0xFF &&
      static_cast<unsigned char>(bytes[1]) == 0xD8) {
    // libjpeg fills a truncated JPEG with grey and succeeds; a missing
    // end-of-image marker (FF D9, trailing zero padding allowed) catches it.
    const std::size_t end = bytes.find_last_not_of('\0');
    if (end == std::string::npos || end < 1 || static_cast<unsigned char>(bytes[end - 1]) != 0xFF ||
        static_cast<unsigned char>(bytes[end]) != 0xD9) {
      Fail(name, "image", "no JPEG end-of-image marker (truncated)", "a complete JPEG image");
    }
  }
  const cv::Mat encoded(1, static_cast<int>(bytes.size()), CV_8U, const_cast<char*>(bytes.data()));
  cv::Mat decoded;
  try {
    decoded = cv::imdecode(encoded, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    Fail(name, "image", std::string("cannot be decoded (") + e.what() + ")", "a valid PNG or JPEG image");
  }
  if (decoded.empty()) Fail(name, "image", "cannot be decoded (corrupt or truncated)", "a valid PNG or JPEG image");
  if (decoded.cols != camera.width || decoded.rows != camera.height) {
    Fail(name, "image size", fmt::format("{} x {} pixels", decoded.cols, decoded.rows), expected_size);
  }
  double scale = 0.0;
  if (decoded.depth() == CV_8U) {
    scale = 1.0 / 255.0;
  } else if (decoded.depth() == CV_16U) {
    scale = 1.0 / 65535.0;
  } else {
    Fail(name, "image depth", fmt::format("OpenCV depth {}", decoded.depth()), "8 or 16 bits per channel");
  }
  if (decoded.channels() != 1 && decoded.channels() != 3 && decoded.channels() != 4) {
    Fail(name, "image channels", fmt::format("{} channels", decoded.channels()), "grey, RGB or RGBA");
  }
  GreyImage image;
  image.t_us = file.t_us;
  if (channel == ImageChannel::kExcessGreen) {
    if (decoded.channels() == 1) {
      Fail(name, "image channels", "1 channel (grey)",
           "a colour image for the excess-green channel (--image-channel exg)");
    }
    std::vector<cv::Mat> bgr;
    cv::split(decoded, bgr);
    cv::Mat b, g, r;
    bgr[0].convertTo(b, CV_32F, scale);
    bgr[1].convertTo(g, CV_32F, scale);
    bgr[2].convertTo(r, CV_32F, scale);
    image.intensity = (2.0f * g - r - b + 2.0f) * 0.25f;  // [-2, 2] -> [0, 1]
    return image;
  }
  cv::Mat grey;
  switch (decoded.channels()) {
    case 1: grey = decoded; break;
    case 3: cv::cvtColor(decoded, grey, cv::COLOR_BGR2GRAY); break;
    default: cv::cvtColor(decoded, grey, cv::COLOR_BGRA2GRAY); break;
  }
  grey.convertTo(image.intensity, CV_32F, scale);
  return image;
}

void WriteImage(const fs::path& path, const cv::Mat& image) {
  const std::string extension = Lowercase(path.extension().string());
  if (!IsImageExtension(extension)) {
    throw std::invalid_argument("WriteImage: " + path.string() + ": not .png/.jpg/.jpeg");
  }
  if (image.depth() != CV_8U && image.depth() != CV_16U) {
    throw std::invalid_argument("WriteImage: " + path.string() + ": image must be 8- or 16-bit");
  }
  if (extension != ".png" && image.depth() != CV_8U) {
    throw std::invalid_argument("WriteImage: " + path.string() + ": JPEG holds 8-bit images only");
  }
  std::vector<int> parameters;
  if (extension != ".png") parameters = {cv::IMWRITE_JPEG_QUALITY, 95};
  std::vector<unsigned char> encoded;
  if (!cv::imencode(extension, image, encoded, parameters)) {
    throw std::runtime_error("WriteImage: cannot encode " + path.string());
  }
  WriteBinaryFile(path, encoded.data(), encoded.size());
}

// ---- scans ----------------------------------------------------------------------------

std::size_t ScanRecordCount(const SensorFile& file) {
  std::error_code error;
  const auto size = fs::file_size(file.path, error);
  if (error) Fail(file.path.string(), "file", "cannot read its size (" + error.message() + ")", "a readable file");
  if (size % sizeof(LidarPoint) != 0) {
    Fail(file.path.string(), "file size", fmt::format("{} bytes", size),
         "a multiple of 16 bytes (float32 x, y, z, reflectance per point)");
  }
  return static_cast<std::size_t>(size / sizeof(LidarPoint));
}

LidarScan ReadScan(const SensorFile& file) {
  ScanRecordCount(file);  // checks the size before reading
  return ParseScan(ReadBinaryFile(file.path, kMaxDataFileBytes), file.path.string(), file.t_us);
}

LidarScan ParseScan(const std::string& bytes, const std::string& name, TimeUs t_us) {
  if (bytes.size() % sizeof(LidarPoint) != 0) {  // also when the file changed after ScanRecordCount
    Fail(name, "file size", fmt::format("{} bytes", bytes.size()), "a multiple of 16 bytes");
  }
  const std::size_t records = bytes.size() / sizeof(LidarPoint);
  LidarScan scan;
  scan.t_us = t_us;
  scan.points.resize(records);
  if (records > 0) std::memcpy(scan.points.data(), bytes.data(), bytes.size());  // data() may be null when empty
  const auto no_return = [](const LidarPoint& p) {
    return !(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z) && std::isfinite(p.reflectance));
  };
  const auto kept_end = std::remove_if(scan.points.begin(), scan.points.end(), no_return);
  scan.no_returns = static_cast<std::size_t>(scan.points.end() - kept_end);
  scan.points.erase(kept_end, scan.points.end());
  return scan;
}

void WriteScan(const fs::path& path, const std::vector<LidarPoint>& points) {
  WriteBinaryFile(path, points.data(), points.size() * sizeof(LidarPoint));
}

}  // namespace scenecal::io
