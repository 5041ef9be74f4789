#include "io/pcd.hpp"

#include <cmath>
#include <cstring>
#include <limits>
#include <optional>
#include <sstream>

#include <fmt/format.h>
#include <lzf.h>

#include "io/yaml_fields.hpp"

namespace scenecal::io {

namespace {

using detail::Fail;

struct PcdField {
  std::string name;
  std::size_t size = 4;   // bytes per element
  char type = 'F';        // F float, U unsigned, I signed
  std::size_t count = 1;  // elements per point
  std::size_t offset = 0; // bytes from the start of the point (binary layout)
};

constexpr std::size_t kMaxFields = 1024;
constexpr std::size_t kMaxPointBytes = 1 << 20;
// LZF codes at most 264 bytes in a 3-byte back-reference, so a stream cannot
// expand by more than ~88x; a header claiming more is corrupt (and must not
// make us allocate it).
constexpr std::size_t kMaxLzfExpansion = 100;

std::vector<std::string_view> Tokens(std::string_view line) {
  std::vector<std::string_view> tokens;
  std::size_t pos = 0;
  while (pos < line.size()) {
    while (pos < line.size() && (line[pos] == ' ' || line[pos] == '\t' || line[pos] == '\r')) ++pos;
    const std::size_t start = pos;
    while (pos < line.size() && line[pos] != ' ' && line[pos] != '\t' && line[pos] != '\r') ++pos;
    if (pos > start) tokens.push_back(line.substr(start, pos - start));
  }
  return tokens;
}

double ReadValue(const unsigned char* bytes, const PcdField& field) {
  switch (field.type) {
    case 'F':
      if (field.size == 4) { float v; std::memcpy(&v, bytes, 4); return v; }
      double d; std::memcpy(&d, bytes, 8); return d;
    case 'U':
      switch (field.size) {
        case 1: return *bytes;
        case 2: { std::uint16_t v; std::memcpy(&v, bytes, 2); return v; }
        case 4: { std::uint32_t v; std::memcpy(&v, bytes, 4); return v; }
        default: { std::uint64_t v; std::memcpy(&v, bytes, 8); return static_cast<double>(v); }
      }
    default:
      switch (field.size) {
        case 1: { std::int8_t v; std::memcpy(&v, bytes, 1); return v; }
        case 2: { std::int16_t v; std::memcpy(&v, bytes, 2); return v; }
        case 4: { std::int32_t v; std::memcpy(&v, bytes, 4); return v; }
        default: { std::int64_t v; std::memcpy(&v, bytes, 8); return static_cast<double>(v); }
      }
  }
}

int FindField(const std::vector<PcdField>& fields, std::initializer_list<std::string_view> names) {
  for (const std::string_view name : names) {
    for (std::size_t i = 0; i < fields.size(); ++i) {
      if (fields[i].name == name) return static_cast<int>(i);
    }
  }
  return -1;
}

// The header: its fields with their layout, the point count and the data's encoding and start.
struct PcdHeader {
  std::vector<PcdField> fields;
  std::optional<std::size_t> width, height, points_claimed;
  bool have_size = false, have_type = false;
  std::string encoding;          // empty until the DATA line
  std::size_t point_count = 0;   // WIDTH x HEIGHT
  std::size_t point_bytes = 0;   // bytes per point (binary layout)
  std::size_t data_start = 0;    // byte of the file where the data starts
  std::size_t line_number = 0;   // the DATA line's
};

// One "KEY values" line of the header (tokens[0] is the key).
void ParseHeaderLine(const std::vector<std::string_view>& tokens, const std::string& name, const std::string& where,
                     PcdHeader* header) {
  const std::string key(tokens[0]);
  const std::size_t values = tokens.size() - 1;
  std::vector<PcdField>& fields = header->fields;
  const auto number = [&](std::size_t i, std::size_t max_value) {
    std::size_t value = 0;
    if (!detail::ParseWholeToken(tokens[i], &value) || value > max_value) {
      Fail(name, where, fmt::format("'{}'", tokens[i]), fmt::format("a whole number up to {}", max_value));
    }
    return value;
  };
  if (key == "VERSION") {
    return;  // 0.7 and the older .7 layouts share these keys
  } else if (key == "FIELDS" || key == "COLUMNS") {
    if (values == 0 || values > kMaxFields) {
      Fail(name, where, fmt::format("{} fields", values), "1 to 1024 field names");
    }
    fields.assign(values, PcdField{});
    for (std::size_t i = 0; i < values; ++i) fields[i].name = std::string(tokens[i + 1]);
  } else if (key == "SIZE" || key == "TYPE" || key == "COUNT") {
    if (fields.empty()) Fail(name, where, key + " before FIELDS", "FIELDS first");
    if (values != fields.size()) {
      Fail(name, where, fmt::format("{} values", values), fmt::format("{} values, one per field", fields.size()));
    }
    for (std::size_t i = 0; i < values; ++i) {
      if (key == "SIZE") {
        fields[i].size = number(i + 1, 8);
        if (fields[i].size != 1 && fields[i].size != 2 && fields[i].size != 4 && fields[i].size != 8) {
          Fail(name, where, fmt::format("size {}", fields[i].size), "1, 2, 4 or 8 bytes");
        }
      } else if (key == "TYPE") {
        if (tokens[i + 1].size() != 1 || std::string_view("FUI").find(tokens[i + 1][0]) == std::string_view::npos) {
          Fail(name, where, fmt::format("type '{}'", tokens[i + 1]), "F, U or I");
        }
        fields[i].type = tokens[i + 1][0];
      } else {
        fields[i].count = number(i + 1, kMaxPointBytes);
        if (fields[i].count == 0) Fail(name, where, "count 0", "at least 1 element per field");
      }
    }
    header->have_size = header->have_size || key == "SIZE";
    header->have_type = header->have_type || key == "TYPE";
  } else if (key == "WIDTH") {
    if (values != 1) Fail(name, where, fmt::format("{} values", values), "one number");
    header->width = number(1, std::size_t{1} << 40);
  } else if (key == "HEIGHT") {
    if (values != 1) Fail(name, where, fmt::format("{} values", values), "one number");
    header->height = number(1, std::size_t{1} << 40);
  } else if (key == "POINTS") {
    if (values != 1) Fail(name, where, fmt::format("{} values", values), "one number");
    header->points_claimed = number(1, std::size_t{1} << 40);
  } else if (key == "VIEWPOINT") {
    if (values != 7) Fail(name, where, fmt::format("{} values", values), "7 numbers (tx ty tz qw qx qy qz)");
    for (std::size_t i = 1; i <= values; ++i) {  // not used, but a corrupt header shows here too
      double value = 0;
      if (!detail::ParseWholeToken(tokens[i], &value) || !std::isfinite(value)) {
        Fail(name, where, fmt::format("'{}'", tokens[i]), "7 finite numbers (tx ty tz qw qx qy qz)");
      }
    }
  } else if (key == "DATA") {
    if (values != 1) Fail(name, where, fmt::format("{} values", values), "ascii, binary or binary_compressed");
    header->encoding = std::string(tokens[1]);
    if (header->encoding != "ascii" && header->encoding != "binary" && header->encoding != "binary_compressed") {
      Fail(name, where, "'" + header->encoding + "'", "ascii, binary or binary_compressed");
    }
  } else {
    Fail(name, where, "unknown header key '" + key + "'",
         "VERSION, FIELDS, SIZE, TYPE, COUNT, WIDTH, HEIGHT, VIEWPOINT, POINTS or DATA");
  }
}

// The keys a header must have and their agreement; sets the point count and
// the fields' offsets.
void CheckHeader(const std::string& name, PcdHeader* header) {
  if (header->fields.empty()) Fail(name, "header FIELDS", "missing", "a FIELDS line before DATA");
  if (!header->have_size || !header->have_type) {
    Fail(name, "header SIZE/TYPE", "missing", "SIZE and TYPE lines before DATA");
  }
  if (!header->width || !header->height) {
    Fail(name, "header WIDTH/HEIGHT", "missing", "WIDTH and HEIGHT lines before DATA");
  }
  const std::size_t width = *header->width, height = *header->height;
  // WIDTH and HEIGHT are each below 2^40, so the product fits 64 bits only if checked.
  if (height != 0 && width > (std::size_t{1} << 40) / height) {
    Fail(name, "header WIDTH/HEIGHT", fmt::format("{} x {} points", width, height), "at most 2^40 points");
  }
  header->point_count = width * height;
  if (header->points_claimed && *header->points_claimed != header->point_count) {
    Fail(name, "header POINTS",
         fmt::format("POINTS {} but WIDTH x HEIGHT = {}", *header->points_claimed, header->point_count),
         "POINTS = WIDTH * HEIGHT");
  }
  header->point_bytes = 0;
  for (PcdField& field : header->fields) {
    if (field.type == 'F' && field.size != 4 && field.size != 8) {
      Fail(name, "header SIZE/TYPE", fmt::format("field {}: float of {} bytes", field.name, field.size),
           "F of size 4 or 8");
    }
    field.offset = header->point_bytes;
    header->point_bytes += field.size * field.count;
    if (header->point_bytes > kMaxPointBytes) {
      Fail(name, "header SIZE/COUNT", "more than 1 MiB per point", "a plausible point layout");
    }
  }
}

// The header: one "KEY values" per line up to and including DATA, checked.
PcdHeader ParseHeader(const std::string& bytes, const std::string& name) {
  PcdHeader header;
  std::size_t pos = 0;
  while (header.encoding.empty()) {
    if (pos >= bytes.size()) {
      Fail(name, "header", "the file ends before the DATA line", "a PCD v0.7 header ending in DATA");
    }
    std::size_t end = bytes.find('\n', pos);
    if (end == std::string::npos) end = bytes.size();
    const std::string_view line(bytes.data() + pos, end - pos);
    pos = end + 1;
    ++header.line_number;
    if (header.line_number > 1000) Fail(name, "header", "more than 1000 header lines", "a PCD header ending in DATA");
    const std::vector<std::string_view> tokens = Tokens(line);
    if (tokens.empty() || tokens[0].front() == '#') continue;
    ParseHeaderLine(tokens, name, fmt::format("header line {} ({})", header.line_number, tokens[0]), &header);
  }
  header.data_start = std::min(pos, bytes.size());
  CheckHeader(name, &header);
  return header;
}

// The fields read into the cloud's points and timestamps: field indices, -1 when absent.
struct PcdColumns {
  int x, y, z, intensity, timestamp;
};

// Fills the cloud from an accessor value(point, field index) -> double.
template <typename Value>
void FillCloud(std::size_t point_count, const PcdColumns& columns, Value&& value, PcdCloud* cloud) {
  cloud->points.resize(point_count);
  if (columns.timestamp >= 0) cloud->timestamps.resize(point_count);
  for (std::size_t i = 0; i < point_count; ++i) {
    LidarPoint& p = cloud->points[i];
    p.x = static_cast<float>(value(i, static_cast<std::size_t>(columns.x)));
    p.y = static_cast<float>(value(i, static_cast<std::size_t>(columns.y)));
    p.z = static_cast<float>(value(i, static_cast<std::size_t>(columns.z)));
    p.reflectance =
        columns.intensity >= 0 ? static_cast<float>(value(i, static_cast<std::size_t>(columns.intensity))) : 0.0f;
    if (columns.timestamp >= 0) cloud->timestamps[i] = value(i, static_cast<std::size_t>(columns.timestamp));
  }
}

// DATA binary: point-major records of point_bytes.
void ReadBinaryData(const PcdHeader& header, const std::string& bytes, const std::string& name,
                    const PcdColumns& columns, PcdCloud* cloud) {
  const std::size_t available = bytes.size() - header.data_start;
  const auto* data = reinterpret_cast<const unsigned char*>(bytes.data()) + header.data_start;
  const std::size_t point_count = header.point_count, point_bytes = header.point_bytes;
  if (point_count > available / point_bytes) {
    Fail(name, "DATA binary",
         fmt::format("{} bytes of data for {} points of {} bytes", available, point_count, point_bytes),
         fmt::format("{} bytes (POINTS x point size)", point_count * point_bytes));
  }
  const std::vector<PcdField>& fields = header.fields;
  FillCloud(point_count, columns, [&](std::size_t i, std::size_t f) {
    return ReadValue(data + i * point_bytes + fields[f].offset, fields[f]);
  }, cloud);
}

// DATA binary_compressed: two uint32 sizes, then an LZF stream of the field-major data.
void ReadCompressedData(const PcdHeader& header, const std::string& bytes, const std::string& name,
                        const PcdColumns& columns, PcdCloud* cloud) {
  const std::size_t available = bytes.size() - header.data_start;
  const auto* data = reinterpret_cast<const unsigned char*>(bytes.data()) + header.data_start;
  const std::size_t point_count = header.point_count, point_bytes = header.point_bytes;
  if (available < 8) {
    Fail(name, "DATA binary_compressed", "the file ends before the two size words",
         "uint32 compressed and uncompressed sizes");
  }
  std::uint32_t compressed_size = 0, uncompressed_size = 0;
  std::memcpy(&compressed_size, data, 4);
  std::memcpy(&uncompressed_size, data + 4, 4);
  if (compressed_size > available - 8) {
    Fail(name, "DATA binary_compressed",
         fmt::format("compressed size {} but only {} bytes follow", compressed_size, available - 8),
         "the compressed stream inside the file");
  }
  if (point_count > std::numeric_limits<std::uint32_t>::max() / point_bytes ||
      uncompressed_size != point_count * point_bytes) {
    Fail(name, "DATA binary_compressed",
         fmt::format("uncompressed size {} for {} points of {} bytes", uncompressed_size, point_count, point_bytes),
         "uncompressed size = POINTS x point size");
  }
  if (uncompressed_size / kMaxLzfExpansion > compressed_size) {
    Fail(name, "DATA binary_compressed",
         fmt::format("uncompressed size {} from {} compressed bytes", uncompressed_size, compressed_size),
         "at most ~88x LZF expansion");
  }
  std::vector<unsigned char> raw(uncompressed_size);
  if (uncompressed_size > 0) {
    const unsigned int decompressed = lzf_decompress(data + 8, compressed_size, raw.data(), uncompressed_size);
    if (decompressed != uncompressed_size) {
      Fail(name, "DATA binary_compressed", fmt::format("the LZF stream decompresses to {} bytes", decompressed),
           fmt::format("{} bytes (uncompressed size)", uncompressed_size));
    }
  }
  // Field-major: every point's first field, then every point's second, ...
  const std::vector<PcdField>& fields = header.fields;
  std::vector<std::size_t> field_start(fields.size());
  std::size_t start = 0;
  for (std::size_t f = 0; f < fields.size(); ++f) {
    field_start[f] = start;
    start += point_count * fields[f].size * fields[f].count;
  }
  FillCloud(point_count, columns, [&](std::size_t i, std::size_t f) {
    return ReadValue(raw.data() + field_start[f] + i * fields[f].size * fields[f].count, fields[f]);
  }, cloud);
}

// DATA ascii: one line of values per point (blank lines skipped).
void ReadAsciiData(const PcdHeader& header, const std::string& bytes, const std::string& name,
                   const PcdColumns& columns, PcdCloud* cloud) {
  const std::vector<PcdField>& fields = header.fields;
  const std::size_t point_count = header.point_count;
  const std::size_t available = bytes.size() - header.data_start;
  std::size_t tokens_per_point = 0;
  std::vector<std::size_t> first_token(fields.size());
  for (std::size_t f = 0; f < fields.size(); ++f) {
    first_token[f] = tokens_per_point;
    tokens_per_point += fields[f].count;
  }
  // Each value takes at least one character and one separator.
  if (point_count > (available + 1) / (2 * tokens_per_point)) {
    Fail(name, "DATA ascii", fmt::format("{} bytes of data for {} points", available, point_count),
         "one line per point as POINTS says");
  }
  std::vector<double> values(point_count * fields.size());
  std::size_t cursor = header.data_start;
  std::size_t line_number = header.line_number;
  for (std::size_t i = 0; i < point_count; ++i) {
    std::vector<std::string_view> tokens;
    while (tokens.empty()) {  // skip blank lines
      if (cursor >= bytes.size()) {
        Fail(name, "DATA ascii", fmt::format("the file ends after {} of {} points", i, point_count),
             "POINTS lines of data");
      }
      std::size_t end = bytes.find('\n', cursor);
      if (end == std::string::npos) end = bytes.size();
      tokens = Tokens(std::string_view(bytes.data() + cursor, end - cursor));
      cursor = end + 1;
      ++line_number;
    }
    if (tokens.size() != tokens_per_point) {
      Fail(name, fmt::format("line {}", line_number), fmt::format("{} values", tokens.size()),
           fmt::format("{} values per point", tokens_per_point));
    }
    for (std::size_t f = 0; f < fields.size(); ++f) {
      double value = 0;
      const std::string_view token = tokens[first_token[f]];
      if (!detail::ParseWholeToken(token, &value)) {
        Fail(name, fmt::format("line {} field {}", line_number, fields[f].name), fmt::format("'{}'", token),
             "a number");
      }
      values[i * fields.size() + f] = value;
    }
  }
  FillCloud(point_count, columns, [&](std::size_t i, std::size_t f) { return values[i * fields.size() + f]; }, cloud);
}

}  // namespace

PcdCloud ParsePcd(const std::string& bytes, const std::string& name) {
  const PcdHeader header = ParseHeader(bytes, name);
  const std::vector<PcdField>& fields = header.fields;
  const PcdColumns columns{FindField(fields, {"x"}), FindField(fields, {"y"}), FindField(fields, {"z"}),
                           FindField(fields, {"intensity", "reflectance", "i"}),
                           FindField(fields, {"timestamp", "time", "t"})};
  if (columns.x < 0 || columns.y < 0 || columns.z < 0) {
    Fail(name, "header FIELDS", "no x, y and z fields", "fields named x, y and z");
  }

  PcdCloud cloud;
  cloud.width = *header.width;
  cloud.height = *header.height;
  cloud.data_encoding = header.encoding;
  for (const PcdField& field : fields) cloud.field_names.push_back(field.name);
  cloud.has_intensity = columns.intensity >= 0;
  if (header.encoding == "binary") {
    ReadBinaryData(header, bytes, name, columns, &cloud);
  } else if (header.encoding == "binary_compressed") {
    ReadCompressedData(header, bytes, name, columns, &cloud);
  } else {
    ReadAsciiData(header, bytes, name, columns, &cloud);
  }
  return cloud;
}

PcdCloud ReadPcd(const std::filesystem::path& path) {
  return ParsePcd(detail::ReadTextFile(path, std::size_t{4} << 30), path.string());
}

}  // namespace scenecal::io
