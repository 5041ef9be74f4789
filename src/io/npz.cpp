#include "io/npz.hpp"

#include <zip.h>

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cstring>
#include <memory>
#include <optional>

#include <fmt/format.h>

#include "io/yaml_fields.hpp"

namespace scenecal::io {

namespace fs = std::filesystem;
using detail::Fail;

namespace {

constexpr char kNpyExpected[] = "a NumPy .npy array (numpy.lib.format version 1-3)";

// The element type of a .npy array from its 'descr' (e.g. '<f8', '|u1').
struct ElementType {
  char kind = 'f';  // f float, i signed, u unsigned
  std::size_t size = 8;
  bool big_endian = false;
};

std::optional<ElementType> ParseDescr(const std::string& descr) {
  if (descr.size() != 3) return std::nullopt;
  ElementType type;
  const char order = descr[0];
  if (order != '<' && order != '>' && order != '|' && order != '=') return std::nullopt;
  type.big_endian = order == '>';
  type.kind = descr[1];
  type.size = static_cast<std::size_t>(descr[2] - '0');
  const bool float_ok = type.kind == 'f' && (type.size == 4 || type.size == 8);
  const bool int_ok = (type.kind == 'i' || type.kind == 'u') &&
                      (type.size == 1 || type.size == 2 || type.size == 4 || type.size == 8);
  if (!float_ok && !int_ok) return std::nullopt;
  return type;
}

// One element at `data` as a double (the host is little-endian: checked below).
double ReadElement(const unsigned char* data, const ElementType& type) {
  unsigned char bytes[8];
  std::memcpy(bytes, data, type.size);
  if (type.big_endian) std::reverse(bytes, bytes + type.size);
  const auto load = [&bytes]<typename T>(T) {
    T value;
    std::memcpy(&value, bytes, sizeof(T));
    return static_cast<double>(value);
  };
  switch (type.kind) {
    case 'f':
      return type.size == 4 ? load(float{}) : load(double{});
    case 'i':
      return type.size == 1   ? load(std::int8_t{})
             : type.size == 2 ? load(std::int16_t{})
             : type.size == 4 ? load(std::int32_t{})
                              : load(std::int64_t{});
    default:
      return type.size == 1   ? load(std::uint8_t{})
             : type.size == 2 ? load(std::uint16_t{})
             : type.size == 4 ? load(std::uint32_t{})
                              : load(std::uint64_t{});
  }
}

// The value of `key` in the header's Python dict literal, as written: a
// quoted string, True, False or a parenthesised tuple. (A scan, not a regular
// expression: the header is read for every cloud.)
std::optional<std::string> HeaderValue(const std::string& header, const std::string& key) {
  for (const char quote : {'\'', '"'}) {
    const std::string quoted = std::string(1, quote) + key + quote;
    std::size_t pos = header.find(quoted);
    if (pos == std::string::npos) continue;
    pos += quoted.size();
    while (pos < header.size() && header[pos] == ' ') ++pos;
    if (pos >= header.size() || header[pos] != ':') return std::nullopt;
    ++pos;
    while (pos < header.size() && header[pos] == ' ') ++pos;
    if (pos >= header.size()) return std::nullopt;
    const char first = header[pos];
    const char closing = first == '(' ? ')' : (first == '\'' || first == '"') ? first : '\0';
    if (closing != '\0') {
      const std::size_t end = header.find(closing, pos + 1);
      if (end == std::string::npos) return std::nullopt;
      return header.substr(pos, end - pos + 1);
    }
    for (const char* word : {"True", "False"}) {
      if (header.compare(pos, std::strlen(word), word) == 0) return std::string(word);
    }
    return std::nullopt;
  }
  return std::nullopt;
}

}  // namespace

NpyArray ParseNpy(const std::string& bytes, const std::string& name) {
  static_assert(std::endian::native == std::endian::little, "the .npy reader assumes a little-endian host");
  const auto* data = reinterpret_cast<const unsigned char*>(bytes.data());
  if (bytes.size() < 10 || std::memcmp(data, "\x93NUMPY", 6) != 0) {
    Fail(name, "magic", "no \\x93NUMPY signature", kNpyExpected);
  }
  const int major = data[6];
  std::size_t header_length = 0;
  std::size_t header_start = 0;
  if (major == 1) {
    header_length = std::size_t{data[8]} | (std::size_t{data[9]} << 8);
    header_start = 10;
  } else if (major == 2 || major == 3) {
    if (bytes.size() < 12) Fail(name, "header", "truncated", kNpyExpected);
    header_length = std::size_t{data[8]} | (std::size_t{data[9]} << 8) | (std::size_t{data[10]} << 16) |
                    (std::size_t{data[11]} << 24);
    header_start = 12;
  } else {
    Fail(name, "version", fmt::format("format version {}", major), kNpyExpected);
  }
  if (header_length > bytes.size() - header_start) {
    Fail(name, "header", fmt::format("claims {} bytes, past the end of the file", header_length), kNpyExpected);
  }
  const std::string header = bytes.substr(header_start, header_length);
  const std::size_t data_start = header_start + header_length;

  const std::optional<std::string> descr_text = HeaderValue(header, "descr");
  if (!descr_text || descr_text->size() < 2) Fail(name, "header.descr", "missing", "an element type such as '<f8'");
  const std::string descr = descr_text->substr(1, descr_text->size() - 2);
  const std::optional<ElementType> type = ParseDescr(descr);
  if (!type) {
    Fail(name, "header.descr", "'" + descr + "'", "a number type: float32/64 or (u)int8..64 ('<f8', '<f4', ...)");
  }
  const std::optional<std::string> order = HeaderValue(header, "fortran_order");
  if (!order || (*order != "True" && *order != "False")) {
    Fail(name, "header.fortran_order", order ? *order : "missing", "True or False");
  }
  const bool fortran_order = *order == "True";
  const std::optional<std::string> shape_text = HeaderValue(header, "shape");
  if (!shape_text) Fail(name, "header.shape", "missing", "a tuple of 1 or 2 sizes");
  std::vector<std::uint64_t> shape;
  {
    const std::string inner = shape_text->substr(1, shape_text->size() - 2);
    std::size_t pos = 0;
    while (pos < inner.size()) {
      const std::size_t comma = std::min(inner.find(',', pos), inner.size());
      std::string token = inner.substr(pos, comma - pos);
      token.erase(std::remove(token.begin(), token.end(), ' '), token.end());
      pos = comma + 1;
      if (token.empty()) continue;  // the trailing comma of "(5,)"
      std::uint64_t value = 0;
      if (!detail::ParseWholeToken(token, &value)) {
        Fail(name, "header.shape", "'" + *shape_text + "'", "a tuple of non-negative integers");
      }
      shape.push_back(value);
    }
  }
  if (shape.empty() || shape.size() > 2) {
    Fail(name, "header.shape", "'" + *shape_text + "'", "an array of 1 or 2 dimensions");
  }
  NpyArray array;
  array.rows = shape[0];
  array.cols = shape.size() == 2 ? shape[1] : 1;
  // Overflow-safe: the product is compared with the bytes actually present.
  const std::size_t available = bytes.size() - data_start;
  const std::size_t max_elements = available / type->size;
  if ((array.cols != 0 && array.rows > max_elements / array.cols) ||
      array.rows * array.cols * type->size != available) {
    Fail(name, "data", fmt::format("{} bytes for shape {} of {}-byte elements", available, *shape_text, type->size),
         "exactly rows x columns x element size bytes after the header");
  }
  array.values.resize(array.rows * array.cols);
  // An empty array ends here: a shape such as (10^9, 0) would otherwise loop 10^9 times over no element.
  if (array.values.empty()) return array;
  const unsigned char* elements = data + data_start;
  for (std::size_t r = 0; r < array.rows; ++r) {
    for (std::size_t c = 0; c < array.cols; ++c) {
      const std::size_t stored = fortran_order ? c * array.rows + r : r * array.cols + c;
      array.values[r * array.cols + c] = ReadElement(elements + stored * type->size, *type);
    }
  }
  return array;
}

NpyArray ParseNpz(const std::string& archive_bytes, const std::string& name, const std::string& member,
                  std::size_t max_member_bytes) {
  constexpr char kExpected[] = "a NumPy .npz archive (zip of .npy files)";
  zip_error_t error;
  zip_error_init(&error);
  zip_source_t* source = zip_source_buffer_create(archive_bytes.data(), archive_bytes.size(), 0, &error);
  if (source == nullptr) {
    const std::string what = zip_error_strerror(&error);
    zip_error_fini(&error);
    Fail(name, "archive", what, kExpected);
  }
  zip_t* archive = zip_open_from_source(source, ZIP_RDONLY | ZIP_CHECKCONS, &error);
  if (archive == nullptr) {
    zip_source_free(source);
    const std::string what = std::string("not a readable zip archive (") + zip_error_strerror(&error) + ")";
    zip_error_fini(&error);
    Fail(name, "archive", what, kExpected);
  }
  zip_error_fini(&error);
  const std::unique_ptr<zip_t, decltype(&zip_discard)> owner(archive, &zip_discard);

  const zip_int64_t entries = zip_get_num_entries(archive, 0);
  zip_int64_t index = -1;
  if (member.empty()) {
    // numpy.savez(file, data=...) names its array "data".
    index = entries == 1 ? 0 : zip_name_locate(archive, "data.npy", 0);
    if (index < 0) {
      Fail(name, "archive", fmt::format("{} members and none named data.npy", entries), "one array, or one named data");
    }
  } else {
    const std::string file_name = member.ends_with(".npy") ? member : member + ".npy";
    index = zip_name_locate(archive, file_name.c_str(), 0);
    if (index < 0) Fail(name, file_name, "missing", "an array '" + member + "' in the archive");
  }
  zip_stat_t stat;
  zip_stat_init(&stat);
  if (zip_stat_index(archive, static_cast<zip_uint64_t>(index), 0, &stat) != 0 || (stat.valid & ZIP_STAT_SIZE) == 0) {
    Fail(name, "archive", std::string("member cannot be read (") + zip_strerror(archive) + ")", kExpected);
  }
  const std::string member_name = (stat.valid & ZIP_STAT_NAME) != 0 ? stat.name : "member";
  if (stat.size > max_member_bytes) {
    Fail(name, member_name, fmt::format("{} bytes uncompressed", stat.size),
         fmt::format("at most {} bytes", max_member_bytes));
  }
  zip_file_t* file = zip_fopen_index(archive, static_cast<zip_uint64_t>(index), 0);
  if (file == nullptr) {
    Fail(name, member_name, std::string("cannot be opened (") + zip_strerror(archive) + ")", kExpected);
  }
  std::string content(static_cast<std::size_t>(stat.size), '\0');
  const zip_int64_t read = zip_fread(file, content.data(), content.size());
  const bool complete = read == static_cast<zip_int64_t>(content.size());
  std::string problem = complete ? std::string() : zip_error_strerror(zip_file_get_error(file));
  // A short read or a CRC mismatch surfaces here, after the data.
  if (zip_fclose(file) != 0 && problem.empty()) problem = zip_strerror(archive);
  if (!complete || !problem.empty()) {
    Fail(name, member_name, "corrupt or truncated (" + problem + ")", kExpected);
  }
  return ParseNpy(content, name + ":" + member_name);
}

NpyArray ReadNpz(const fs::path& path, const std::string& member) {
  return ParseNpz(detail::ReadTextFile(path, std::size_t{2} << 30), path.string(), member);
}

}  // namespace scenecal::io
