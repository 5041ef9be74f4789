// One table of (value, name) pairs per enum, from which its Parse and Name
// functions and the list of accepted names in error messages are derived:
//   inline constexpr auto kColourNames = MakeEnumNames<Colour>({{Colour::kRed, "red"}, {Colour::kBlue, "blue"}});
//   bool ParseColour(std::string_view name, Colour* colour) { return ParseEnumName(kColourNames, name, colour); }
// A value may appear more than once (aliases accepted by the parse): its first
// entry is its name.
#pragma once

#include <array>
#include <cstddef>
#include <optional>
#include <string>
#include <string_view>

namespace scenecal {

template <class E>
struct EnumNameEntry {
  E value;
  const char* name;
};

template <class E, std::size_t N>
using EnumNames = std::array<EnumNameEntry<E>, N>;

// The table of the given entries (N deduced).
template <class E, std::size_t N>
constexpr EnumNames<E, N> MakeEnumNames(const EnumNameEntry<E> (&entries)[N]) {
  return std::to_array(entries);
}

// The value named `name` (exact match) into *value; false, *value untouched, if none.
template <class E, std::size_t N>
constexpr bool ParseEnumName(const EnumNames<E, N>& table, std::string_view name, E* value) {
  for (const EnumNameEntry<E>& entry : table) {
    if (name == entry.name) {
      *value = entry.value;
      return true;
    }
  }
  return false;
}

// The same as an optional: nullopt if no entry is named `name`.
template <class E, std::size_t N>
constexpr std::optional<E> ParseEnumName(const EnumNames<E, N>& table, std::string_view name) {
  E value{};
  if (ParseEnumName(table, name, &value)) return value;
  return std::nullopt;
}

// The name of value (its first entry); "unknown" for a value not in the table.
template <class E, std::size_t N>
constexpr const char* EnumName(const EnumNames<E, N>& table, E value) {
  for (const EnumNameEntry<E>& entry : table) {
    if (entry.value == value) return entry.name;
  }
  return "unknown";
}

// The names of the table's values, aliases left out, joined by " | "
// (e.g. "pinhole | radtan | equidistant"), for error and help messages.
template <class E, std::size_t N>
std::string EnumNameList(const EnumNames<E, N>& table) {
  std::string list;
  for (std::size_t i = 0; i < N; ++i) {
    bool alias = false;  // a later entry of a value named before
    for (std::size_t j = 0; j < i; ++j) alias = alias || table[j].value == table[i].value;
    if (alias) continue;
    if (!list.empty()) list += " | ";
    list += table[i].name;
  }
  return list;
}

}  // namespace scenecal
