#include "sim/world.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <optional>
#include <vector>

#include "sim/noise.hpp"

namespace scenecal::sim {
namespace {

constexpr double kTwoPi = 6.283185307179586;
constexpr double kInfinity = std::numeric_limits<double>::infinity();
// Angle one pixel of the 1280-px camera subtends (rad): the scale of texture
// filtering for fine periodic patterns.
constexpr double kPixelAngle = 1.0 / 983.0;

// Object kinds in the grid's packed references.
constexpr std::uint32_t kKindBox = 0, kKindCylinder = 1, kKindSphere = 2;
constexpr std::uint32_t kKindShift = 30, kIndexMask = (1u << kKindShift) - 1;

double Clamp01(double x) { return std::clamp(x, 0.0, 1.0); }
double Mix(double a, double b, double w) { return a + (b - a) * w; }
double Fract(double x) { return x - std::floor(x); }
double HashUnit(std::uint64_t seed, std::int64_t a, std::int64_t b = 0) {
  return UniformFromHash(HashKey(seed, static_cast<std::uint64_t>(a), static_cast<std::uint64_t>(b), 77));
}

// Curvature of the centre line: three long sinusoids (1/m).
struct CurvatureTerms {
  std::array<double, 3> amplitude{}, wavenumber{}, phase{};
  double Evaluate(double s) const {
    double k = 0.0;
    for (int i = 0; i < 3; ++i) k += amplitude[i] * std::sin(wavenumber[i] * s + phase[i]);
    return k;
  }
};

CurvatureTerms MakeCurvature(std::uint64_t seed) {
  KeyedRandom random(seed, 101);
  CurvatureTerms terms;
  double total = 0.0;
  for (int i = 0; i < 3; ++i) {
    terms.amplitude[i] = random.Uniform(0.4, 1.0);
    terms.wavenumber[i] = kTwoPi / random.Uniform(160.0, 420.0);
    terms.phase[i] = random.Uniform(0.0, kTwoPi);
    total += terms.amplitude[i];
  }
  const double max_curvature = 1.0 / 110.0;  // gentle: radius >= 110 m
  for (double& a : terms.amplitude) a *= max_curvature / total;
  return terms;
}

}  // namespace

const char* MaterialName(Material material) {
  switch (material) {
    case Material::kAsphalt: return "asphalt";
    case Material::kRoadPaint: return "road_paint";
    case Material::kPatchDark: return "patch_dark";
    case Material::kPatchConcrete: return "patch_concrete";
    case Material::kManhole: return "manhole";
    case Material::kPaving: return "paving";
    case Material::kKerb: return "kerb";
    case Material::kBrick: return "brick";
    case Material::kPlaster: return "plaster";
    case Material::kGlass: return "glass";
    case Material::kWindowFrame: return "window_frame";
    case Material::kDoor: return "door";
    case Material::kVegetation: return "vegetation";
    case Material::kGrass: return "grass";
    case Material::kBark: return "bark";
    case Material::kMetal: return "metal";
    case Material::kSign: return "sign";
    case Material::kCarPaint: return "car_paint";
    case Material::kCarGlass: return "car_glass";
    case Material::kTyre: return "tyre";
    case Material::kStone: return "stone";
    case Material::kCount: break;
  }
  return "unknown";
}

// ---------------------------------------------------------------------------
// Centre line

CentreLine::CentreLine(std::uint64_t seed, double s_begin, double s_end) : s_begin_(s_begin), s_end_(s_end) {
  const CurvatureTerms terms = MakeCurvature(seed);
  const auto count = static_cast<std::size_t>(std::ceil((s_end - s_begin) / kStep)) + 2;
  heading_.resize(count);
  position_.resize(count);
  curvature_.resize(count);
  KeyedRandom random(seed, 102);
  const double heading_at_zero = random.Uniform(0.0, kTwoPi);
  // Integrate from s = 0 both ways so that the street passes the world origin at s = 0.
  const auto i_zero = static_cast<std::ptrdiff_t>(std::llround(-s_begin / kStep));
  const auto integrate = [&](std::ptrdiff_t from, std::ptrdiff_t to) {
    const double step = to > from ? kStep : -kStep;
    const double s_from = s_begin + static_cast<double>(from) * kStep;
    const double heading_mid = heading_[static_cast<std::size_t>(from)] + 0.5 * step * terms.Evaluate(s_from + 0.5 * step);
    heading_[static_cast<std::size_t>(to)] = heading_[static_cast<std::size_t>(from)] + step * terms.Evaluate(s_from + 0.5 * step);
    position_[static_cast<std::size_t>(to)] =
        position_[static_cast<std::size_t>(from)] + step * Eigen::Vector2d(std::cos(heading_mid), std::sin(heading_mid));
  };
  const auto n = static_cast<std::ptrdiff_t>(count);
  const std::ptrdiff_t start = std::clamp<std::ptrdiff_t>(i_zero, 0, n - 1);
  heading_[static_cast<std::size_t>(start)] = heading_at_zero;
  position_[static_cast<std::size_t>(start)] = Eigen::Vector2d::Zero();
  for (std::ptrdiff_t i = start; i + 1 < n; ++i) integrate(i, i + 1);
  for (std::ptrdiff_t i = start; i > 0; --i) integrate(i, i - 1);
  for (std::size_t i = 0; i < count; ++i) curvature_[i] = terms.Evaluate(s_begin + static_cast<double>(i) * kStep);
}

double CentreLine::Heading(double s) const {
  const double x = (s - s_begin_) / kStep;
  const auto last = static_cast<double>(heading_.size() - 1);
  const double xc = std::clamp(x, 0.0, last - 1e-9);
  const auto i = static_cast<std::size_t>(xc);
  const double f = xc - static_cast<double>(i);
  return heading_[i] + (heading_[i + 1] - heading_[i]) * f;
}

double CentreLine::Curvature(double s) const {
  const double x = (s - s_begin_) / kStep;
  const auto last = static_cast<double>(curvature_.size() - 1);
  const double xc = std::clamp(x, 0.0, last - 1e-9);
  const auto i = static_cast<std::size_t>(xc);
  const double f = xc - static_cast<double>(i);
  return curvature_[i] + (curvature_[i + 1] - curvature_[i]) * f;
}

Eigen::Vector2d CentreLine::Position(double s) const {
  const double x = (s - s_begin_) / kStep;
  const auto last = static_cast<double>(heading_.size() - 1);
  const double xc = std::clamp(std::floor(x), 0.0, last);
  const auto i = static_cast<std::size_t>(xc);
  const double ds = s - (s_begin_ + xc * kStep);  // within the step (or beyond the ends: straight)
  const double heading_mid = heading_[i] + 0.5 * (Heading(s) - heading_[i]);
  return position_[i] + ds * Eigen::Vector2d(std::cos(heading_mid), std::sin(heading_mid));
}

Eigen::Vector2d CentreLine::Tangent(double s) const {
  const double h = Heading(s);
  return {std::cos(h), std::sin(h)};
}

Eigen::Vector2d CentreLine::LeftNormal(double s) const {
  const double h = Heading(s);
  return {-std::sin(h), std::cos(h)};
}

// ---------------------------------------------------------------------------
// Generation

class WorldBuilder {
 public:
  WorldBuilder(World* world, std::uint64_t seed) : w_(*world), seed_(seed) {}

  void Build(double s_begin, double s_end) {
    KeyedRandom random(seed_, 200);
    StreetLayout& layout = w_.layout_;
    layout.road_half_width = random.Uniform(5.3, 5.8);
    layout.lane_line_offset = layout.road_half_width - 2.1;
    layout.driving_lane_offset = 0.5 * layout.lane_line_offset;
    layout.pavement_width_left = random.Uniform(2.4, 3.6);
    layout.pavement_width_right = random.Uniform(2.4, 3.6);
    layout.kerb_height = random.Uniform(0.11, 0.15);
    const double elevation = RadiansFromDeg(random.Uniform(30.0, 55.0));
    const double azimuth = random.Uniform(0.0, kTwoPi);
    w_.sun_direction_ = Eigen::Vector3d(std::cos(elevation) * std::cos(azimuth),
                                        std::cos(elevation) * std::sin(azimuth), std::sin(elevation));
    for (const double side : {+1.0, -1.0}) {
      BuildPavement(side, s_begin, s_end);
      BuildFrontage(side, s_begin, s_end);
      BuildStreetFurniture(side, s_begin, s_end);
      BuildParkedCars(side, s_begin, s_end);
    }
    BuildRoadMarkings(s_begin, s_end);
  }

 private:
  static double RadiansFromDeg(double d) { return d * kTwoPi / 360.0; }
  std::uint32_t Seed(std::uint32_t k) { return static_cast<std::uint32_t>(HashKey(seed_, 300, k, next_seed_++)); }
  const CentreLine& line() const { return w_.centre_line_; }

  // A box centred at street coordinates (s, d), aligned with the street there.
  void AddStreetBox(double s, double d, double length, double width, double z0, double z1, std::uint32_t look,
                    double yaw_offset = 0.0) {
    const Eigen::Vector2d c = line().ToWorld(s, d);
    const double yaw = line().Heading(s) + yaw_offset;
    w_.boxes_.push_back({c.x(), c.y(), z0, z1, 0.5 * length, 0.5 * width, std::cos(yaw), std::sin(yaw), s, look});
    w_.top_z_ = std::max(w_.top_z_, z1);
  }
  void AddStreetCylinder(double s, double d, double radius, double z0, double z1, std::uint32_t look) {
    const Eigen::Vector2d c = line().ToWorld(s, d);
    w_.cylinders_.push_back({c.x(), c.y(), radius, z0, z1, look});
    w_.top_z_ = std::max(w_.top_z_, z1);
  }
  void AddStreetSphere(double s, double d, double z, double radius, std::uint32_t look) {
    const Eigen::Vector2d c = line().ToWorld(s, d);
    w_.spheres_.push_back({c.x(), c.y(), z, radius, look});
    w_.top_z_ = std::max(w_.top_z_, z + radius);
  }
  void AddDecal(double s, double d, double length, double width, std::uint32_t look, bool disc = false,
                double yaw_offset = 0.0) {
    const Eigen::Vector2d c = line().ToWorld(s, d);
    const double yaw = line().Heading(s) + yaw_offset;
    w_.decals_.push_back({c.x(), c.y(), 0.5 * length, 0.5 * width, std::cos(yaw), std::sin(yaw), s, disc, look});
  }

  void BuildPavement(double side, double s_begin, double s_end) {
    const StreetLayout& layout = w_.layout_;
    const double width = side > 0 ? layout.pavement_width_left : layout.pavement_width_right;
    // param: which local v side is the kerb (the road side).
    const std::uint32_t look = w_.AddLook({Material::kPaving, 0.34f, 1.0f, static_cast<float>(-side), Seed(2), -1});
    const double segment = 4.0;
    for (double s = s_begin; s < s_end; s += segment) {
      // Slight overlap so that curved joints leave no gaps.
      AddStreetBox(s + 0.5 * segment, side * (layout.road_half_width + 0.5 * width), segment + 0.15, width, 0.0,
                   layout.kerb_height, look);
    }
  }

  World::Facade MakeFacade(KeyedRandom& random, double half_length, double floor_height) {
    World::Facade f{};
    f.floor_height = floor_height;
    f.window_width = random.Uniform(0.9, 1.5);
    f.window_height = random.Uniform(1.2, 1.8);
    f.sill_height = random.Uniform(0.8, 1.0);
    f.window_spacing = f.window_width + random.Uniform(0.9, 2.4);
    f.window_offset = random.Uniform(0.0, f.window_spacing);
    f.door_width = random.Uniform(1.0, 1.4);
    f.door_height = random.Uniform(2.1, 2.5);
    f.door_u = random.Uniform(-half_length + 0.5, std::max(-half_length + 0.6, half_length - 0.5 - f.door_width));
    f.plinth_height = random.Uniform(0.2, 0.6);
    const bool white_frames = random.Chance(0.6);
    f.frame_albedo = white_frames ? random.Uniform(0.7, 0.85) : random.Uniform(0.08, 0.25);
    // White uPVC frames are middling in the infrared, dark wood or metal frames bright.
    f.frame_ir = white_frames ? random.Uniform(0.35, 0.5) : random.Uniform(0.5, 0.8);
    return f;
  }

  void BuildFrontage(double side, double s_begin, double s_end) {
    const StreetLayout& layout = w_.layout_;
    const double pavement = side > 0 ? layout.pavement_width_left : layout.pavement_width_right;
    const double back_of_pavement = layout.road_half_width + pavement;
    KeyedRandom random(seed_, side > 0 ? 401 : 402);
    double s = s_begin - random.Uniform(0.0, 10.0);
    while (s < s_end) {
      if (random.Chance(0.18)) {  // an alley or a gap between buildings
        const double gap = random.Uniform(2.0, 7.0);
        if (random.Chance(0.5)) {  // with a wall along the pavement
          const std::uint32_t wall =
              w_.AddLook({Material::kStone, static_cast<float>(random.Uniform(0.2, 0.5)), 1.0f, 0.0f, Seed(3), -1});
          AddStreetBox(s + 0.5 * gap, side * (back_of_pavement + 0.15), gap, 0.3, 0.0, random.Uniform(1.2, 2.2), wall);
        }
        s += gap;
        continue;
      }
      const double length = random.Uniform(7.0, 22.0);
      const double setback = random.Chance(0.55) ? 0.0 : random.Uniform(1.0, 4.5);
      const double depth = random.Uniform(8.0, 14.0);
      const int floors = random.Integer(2, 6);
      const double floor_height = random.Uniform(2.9, 3.4);
      const double height = floors * floor_height + random.Uniform(0.2, 0.9);
      const bool brick = random.Chance(0.5);
      World::Look look;
      look.material = brick ? Material::kBrick : Material::kPlaster;
      look.albedo = static_cast<float>(brick ? random.Uniform(0.18, 0.32) : random.Uniform(0.4, 0.85));
      // Paints differ in the infrared independently of their visible shade.
      look.ir_gain = static_cast<float>(random.Uniform(0.35, 1.4));
      look.seed = Seed(4);
      look.facade = static_cast<int>(w_.facades_.size());
      w_.facades_.push_back(MakeFacade(random, 0.5 * length, floor_height));
      const std::uint32_t building = w_.AddLook(look);
      const double s_centre = s + 0.5 * length;
      AddStreetBox(s_centre, side * (back_of_pavement + setback + 0.5 * depth), length, depth, 0.0, height, building);
      if (setback > 0.0) {
        const bool lawn = random.Chance(0.6);
        const std::uint32_t garden =
            w_.AddLook({lawn ? Material::kGrass : Material::kStone, static_cast<float>(lawn ? 0.14 : 0.3), 1.0f, 0.0f,
                        Seed(5), -1});
        AddStreetBox(s_centre, side * (back_of_pavement + 0.5 * setback), length, setback, 0.0, 0.16, garden);
        const double boundary = random.Uniform();
        if (boundary < 0.4) {
          const std::uint32_t wall =
              w_.AddLook({Material::kStone, static_cast<float>(random.Uniform(0.2, 0.5)), 1.0f, 0.0f, Seed(6), -1});
          AddStreetBox(s_centre, side * (back_of_pavement + 0.15), length, 0.3, 0.0, random.Uniform(0.5, 1.1), wall);
        } else if (boundary < 0.7) {
          const std::uint32_t hedge = w_.AddLook({Material::kVegetation, 0.12f, 1.0f, 0.0f, Seed(7), -1});
          AddStreetBox(s_centre, side * (back_of_pavement + 0.45), length - 1.0, std::min(0.9, setback), 0.0,
                       random.Uniform(0.9, 1.8), hedge);
        }
      }
      s += length + (random.Chance(0.5) ? 0.0 : random.Uniform(0.1, 1.0));
    }
  }

  void BuildStreetFurniture(double side, double s_begin, double s_end) {
    const StreetLayout& layout = w_.layout_;
    KeyedRandom random(seed_, side > 0 ? 501 : 502);
    // Street lights.
    for (double s = s_begin + random.Uniform(0.0, 30.0); s < s_end; s += random.Uniform(24.0, 36.0)) {
      const double d = side * (layout.road_half_width + 0.5);
      const double height = random.Uniform(6.0, 8.0);
      const std::uint32_t metal =
          w_.AddLook({Material::kMetal, static_cast<float>(random.Uniform(0.12, 0.4)),
                      static_cast<float>(random.Uniform(0.5, 1.5)), 0.0f, Seed(8), -1});
      AddStreetCylinder(s, d, random.Uniform(0.07, 0.1), 0.0, height, metal);
      AddStreetBox(s, d - side * 0.8, 0.12, 1.6, height - 0.18, height - 0.08, metal);
      AddStreetBox(s, d - side * 1.5, 0.35, 0.6, height - 0.35, height - 0.1, metal);
    }
    // Trees.
    for (double s = s_begin + random.Uniform(0.0, 20.0); s < s_end; s += random.Uniform(11.0, 28.0)) {
      if (!random.Chance(0.75)) continue;
      const double d = side * (layout.road_half_width + random.Uniform(0.9, 1.4));
      const double trunk_height = random.Uniform(2.2, 3.4);
      const double crown = random.Uniform(1.4, 2.7);
      const std::uint32_t bark = w_.AddLook({Material::kBark, static_cast<float>(random.Uniform(0.1, 0.18)),
                                             1.0f, 0.0f, Seed(9), -1});
      const std::uint32_t leaves = w_.AddLook({Material::kVegetation, static_cast<float>(random.Uniform(0.09, 0.16)),
                                               static_cast<float>(random.Uniform(0.8, 1.2)), 0.0f, Seed(10), -1});
      AddStreetCylinder(s, d, random.Uniform(0.12, 0.22), 0.0, trunk_height + crown * 0.5, bark);
      AddStreetSphere(s, d, trunk_height + 0.75 * crown, crown, leaves);
    }
    // Signs, bollards and bins.
    for (double s = s_begin + random.Uniform(0.0, 15.0); s < s_end; s += random.Uniform(8.0, 26.0)) {
      const double kind = random.Uniform();
      const double d = side * (layout.road_half_width + random.Uniform(0.3, 0.7));
      if (kind < 0.4) {
        const std::uint32_t post = w_.AddLook({Material::kMetal, 0.3f, 1.0f, 0.0f, Seed(11), -1});
        const std::uint32_t plate = w_.AddLook({Material::kSign, static_cast<float>(random.Uniform(0.15, 0.8)),
                                                static_cast<float>(random.Uniform(0.8, 1.3)), 0.0f, Seed(12), -1});
        const double top = random.Uniform(2.4, 3.0);
        AddStreetCylinder(s, d, 0.04, 0.0, top, post);
        AddStreetBox(s + 0.06, d, 0.04, random.Uniform(0.5, 0.8), top - random.Uniform(0.5, 0.8), top, plate);
      } else if (kind < 0.7) {
        const std::uint32_t bollard = w_.AddLook({Material::kMetal, static_cast<float>(random.Uniform(0.05, 0.6)),
                                                  static_cast<float>(random.Uniform(0.5, 1.5)), 0.0f, Seed(13), -1});
        for (int i = 0; i < random.Integer(1, 4); ++i)
          AddStreetCylinder(s + 1.5 * i, d, 0.1, 0.0, random.Uniform(0.8, 1.0), bollard);
      } else {
        const std::uint32_t bin = w_.AddLook({Material::kMetal, static_cast<float>(random.Uniform(0.05, 0.5)),
                                              static_cast<float>(random.Uniform(0.5, 1.5)), 0.0f, Seed(14), -1});
        AddStreetBox(s, d + side * 0.2, 0.7, 0.7, 0.0, random.Uniform(1.0, 1.3), bin);
      }
    }
  }

  void BuildParkedCars(double side, double s_begin, double s_end) {
    const StreetLayout& layout = w_.layout_;
    KeyedRandom random(seed_, side > 0 ? 601 : 602);
    static constexpr std::array<double, 8> kPaintAlbedo = {0.04, 0.08, 0.12, 0.22, 0.35, 0.55, 0.75, 0.85};
    for (double s = s_begin + random.Uniform(0.0, 6.0); s < s_end; s += 5.8) {
      if (!random.Chance(0.5)) continue;
      const double length = random.Uniform(3.9, 4.9);
      const double width = random.Uniform(1.7, 1.85);
      const double d = side * (layout.road_half_width - 0.25 - 0.5 * width);
      const double body_z0 = random.Uniform(0.22, 0.3);
      const double body_z1 = random.Uniform(0.95, 1.15);
      const double cabin_z1 = body_z1 + random.Uniform(0.38, 0.52);
      const double albedo = kPaintAlbedo[static_cast<std::size_t>(random.Integer(0, 7))] * random.Uniform(0.9, 1.1);
      // The infrared response of car paint is largely independent of its colour.
      const double ir_gain = random.Uniform(0.25, 1.8);
      const double yaw = random.Uniform(-0.03, 0.03);
      const std::uint32_t body = w_.AddLook({Material::kCarPaint, static_cast<float>(albedo),
                                             static_cast<float>(ir_gain), static_cast<float>(body_z0), Seed(15), -1});
      const std::uint32_t cabin = w_.AddLook({Material::kCarGlass, static_cast<float>(albedo),
                                              static_cast<float>(ir_gain), 0.0f, Seed(16), -1});
      AddStreetBox(s + 0.5 * length, d, length, width, body_z0, body_z1, body, yaw);
      AddStreetBox(s + 0.45 * length, d, 0.55 * length, width - 0.14, body_z1, cabin_z1, cabin, yaw);
      // Wheels: short boxes at the corners below the body.
      const std::uint32_t tyre = w_.AddLook({Material::kTyre, 0.05f, 1.0f, 0.0f, Seed(17), -1});
      for (const double fu : {0.18, 0.82}) {
        AddStreetBox(s + fu * length, d, 0.62, width - 0.05, 0.0, body_z0 + 0.05, tyre, yaw);
      }
    }
  }

  void BuildRoadMarkings(double s_begin, double s_end) {
    const StreetLayout& layout = w_.layout_;
    KeyedRandom random(seed_, 700);
    // Repairs first: markings painted later win where they overlap.
    for (double s = s_begin; s < s_end; s += random.Uniform(3.0, 12.0)) {
      const bool dark = random.Chance(0.6);
      const std::uint32_t look =
          w_.AddLook({dark ? Material::kPatchDark : Material::kPatchConcrete, 0.0f, 1.0f, 0.0f, Seed(18), -1});
      AddDecal(s, random.Uniform(-layout.road_half_width + 0.5, layout.road_half_width - 0.5),
               random.Uniform(0.4, 3.5), random.Uniform(0.3, 2.0), look, false, random.Uniform(-0.35, 0.35));
    }
    for (double s = s_begin + random.Uniform(0.0, 20.0); s < s_end; s += random.Uniform(14.0, 30.0)) {
      const std::uint32_t look = w_.AddLook({Material::kManhole, 0.0f, 1.0f, 0.0f, Seed(19), -1});
      const double r = random.Uniform(0.3, 0.4);
      AddDecal(s, random.Uniform(-layout.road_half_width + 1.0, layout.road_half_width - 1.0), 2 * r, 2 * r, look, true);
    }
    const std::uint32_t paint = w_.AddLook({Material::kRoadPaint, 0.75f, 1.0f, 0.0f, Seed(20), -1});
    // Dashed centre line, solid lines between the lanes and the parking strips.
    for (double s = s_begin; s < s_end; s += 9.0) AddDecal(s + 1.5, 0.0, 3.0, 0.12, paint);
    for (double s = s_begin; s < s_end; s += 3.0) {
      AddDecal(s + 1.5, layout.lane_line_offset, 3.05, 0.1, paint);
      AddDecal(s + 1.5, -layout.lane_line_offset, 3.05, 0.1, paint);
    }
    // Zebra crossings and give-way lines.
    for (double s = s_begin + random.Uniform(40.0, 90.0); s < s_end; s += random.Uniform(110.0, 190.0)) {
      if (random.Chance(0.6)) {
        for (double d = -layout.road_half_width + 0.6; d < layout.road_half_width - 0.4; d += 1.0)
          AddDecal(s, d, 3.0, 0.5, paint);
      } else {
        AddDecal(s, 0.5 * layout.lane_line_offset, 0.3, layout.lane_line_offset, paint);
        for (double d = -layout.lane_line_offset + 0.3; d < -0.2; d += 0.9) AddDecal(s, d, 0.6, 0.3, paint);
      }
    }
  }

  World& w_;
  std::uint64_t seed_;
  std::uint32_t next_seed_ = 0;
};

std::uint32_t World::AddLook(const Look& look) {
  looks_.push_back(look);
  return static_cast<std::uint32_t>(looks_.size() - 1);
}

std::size_t World::ObjectCount() const { return boxes_.size() + cylinders_.size() + spheres_.size() + decals_.size(); }

World World::Generate(std::uint64_t seed, double s_begin, double s_end) {
  World world;
  world.seed_ = seed;
  world.centre_line_ = CentreLine(seed, s_begin - 50.0, s_end + 50.0);
  WorldBuilder builder(&world, seed);
  builder.Build(s_begin, s_end);
  world.BuildGrid();
  return world;
}

void World::BuildGrid() {
  // Bounding boxes in xy of everything.
  struct Bounds {
    double x0, y0, x1, y1;
  };
  std::vector<std::pair<std::uint32_t, Bounds>> objects;
  std::vector<std::pair<std::uint32_t, Bounds>> decals;
  const auto oriented = [](double cx, double cy, double hu, double hv, double c, double s) {
    const double ex = std::abs(c) * hu + std::abs(s) * hv, ey = std::abs(s) * hu + std::abs(c) * hv;
    return Bounds{cx - ex, cy - ey, cx + ex, cy + ey};
  };
  for (std::size_t i = 0; i < boxes_.size(); ++i) {
    const Box& b = boxes_[i];
    objects.push_back({(kKindBox << kKindShift) | static_cast<std::uint32_t>(i),
                       oriented(b.cx, b.cy, b.half_u, b.half_v, b.cos_yaw, b.sin_yaw)});
  }
  for (std::size_t i = 0; i < cylinders_.size(); ++i) {
    const Cylinder& c = cylinders_[i];
    objects.push_back({(kKindCylinder << kKindShift) | static_cast<std::uint32_t>(i),
                       Bounds{c.cx - c.radius, c.cy - c.radius, c.cx + c.radius, c.cy + c.radius}});
  }
  for (std::size_t i = 0; i < spheres_.size(); ++i) {
    const Sphere& s = spheres_[i];
    objects.push_back({(kKindSphere << kKindShift) | static_cast<std::uint32_t>(i),
                       Bounds{s.cx - s.radius, s.cy - s.radius, s.cx + s.radius, s.cy + s.radius}});
  }
  for (std::size_t i = 0; i < decals_.size(); ++i) {
    const Decal& d = decals_[i];
    decals.push_back({static_cast<std::uint32_t>(i), oriented(d.cx, d.cy, d.half_u, d.half_v, d.cos_yaw, d.sin_yaw)});
  }
  Bounds all{kInfinity, kInfinity, -kInfinity, -kInfinity};
  for (const auto& [ref, b] : objects) {
    all = {std::min(all.x0, b.x0), std::min(all.y0, b.y0), std::max(all.x1, b.x1), std::max(all.y1, b.y1)};
  }
  if (objects.empty()) all = {-1, -1, 1, 1};
  grid_x0_ = all.x0 - 1.0;
  grid_y0_ = all.y0 - 1.0;
  grid_nx_ = std::max(1, static_cast<int>(std::ceil((all.x1 + 1.0 - grid_x0_) / cell_size_)));
  grid_ny_ = std::max(1, static_cast<int>(std::ceil((all.y1 + 1.0 - grid_y0_) / cell_size_)));
  const std::size_t cells = static_cast<std::size_t>(grid_nx_) * static_cast<std::size_t>(grid_ny_);
  const auto fill = [&](const std::vector<std::pair<std::uint32_t, Bounds>>& items, std::vector<std::uint32_t>* begin,
                        std::vector<std::uint32_t>* refs) {
    std::vector<std::vector<std::uint32_t>> lists(cells);
    for (const auto& [ref, b] : items) {
      const int ix0 = std::clamp(static_cast<int>(std::floor((b.x0 - grid_x0_) / cell_size_)), 0, grid_nx_ - 1);
      const int ix1 = std::clamp(static_cast<int>(std::floor((b.x1 - grid_x0_) / cell_size_)), 0, grid_nx_ - 1);
      const int iy0 = std::clamp(static_cast<int>(std::floor((b.y0 - grid_y0_) / cell_size_)), 0, grid_ny_ - 1);
      const int iy1 = std::clamp(static_cast<int>(std::floor((b.y1 - grid_y0_) / cell_size_)), 0, grid_ny_ - 1);
      for (int iy = iy0; iy <= iy1; ++iy)
        for (int ix = ix0; ix <= ix1; ++ix) lists[static_cast<std::size_t>(iy) * grid_nx_ + ix].push_back(ref);
    }
    begin->assign(cells + 1, 0);
    refs->clear();
    for (std::size_t c = 0; c < cells; ++c) {
      (*begin)[c] = static_cast<std::uint32_t>(refs->size());
      refs->insert(refs->end(), lists[c].begin(), lists[c].end());
    }
    (*begin)[cells] = static_cast<std::uint32_t>(refs->size());
  };
  fill(objects, &cell_object_begin_, &cell_objects_);
  cell_top_z_.assign(cells, 0.0f);
  for (std::size_t c = 0; c < cells; ++c) {
    for (std::uint32_t k = cell_object_begin_[c]; k < cell_object_begin_[c + 1]; ++k) {
      const std::uint32_t ref = cell_objects_[k], kind = ref >> kKindShift, index = ref & kIndexMask;
      const double top = kind == kKindBox        ? boxes_[index].z1
                         : kind == kKindCylinder ? cylinders_[index].z1
                                                 : spheres_[index].cz + spheres_[index].radius;
      cell_top_z_[c] = std::max(cell_top_z_[c], static_cast<float>(top) + 1e-3f);
    }
  }
  fill(decals, &cell_decal_begin_, &cell_decals_);
}

// ---------------------------------------------------------------------------
// Ray casting

struct World::Candidate {
  double t = kInfinity;
  int kind = -1;  // 0 box, 1 cylinder, 2 sphere, 3 ground
  std::uint32_t index = 0;
  int face_axis = 2;    // box: axis of the face hit (0 u, 1 v, 2 z); cylinder: 0 side, 2 cap
  double face_sign = 1;  // box: side of that face
};

namespace {

// Slab test in the box's local frame; returns the entry distance and face.
inline bool IntersectBox(const World::Box& b, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_min,
                         double t_max, double* t_hit, int* axis, double* sign) {
  const double ox = o.x() - b.cx, oy = o.y() - b.cy;
  const double lo[3] = {ox * b.cos_yaw + oy * b.sin_yaw, -ox * b.sin_yaw + oy * b.cos_yaw, o.z()};
  const double ld[3] = {d.x() * b.cos_yaw + d.y() * b.sin_yaw, -d.x() * b.sin_yaw + d.y() * b.cos_yaw, d.z()};
  const double lower[3] = {-b.half_u, -b.half_v, b.z0};
  const double upper[3] = {b.half_u, b.half_v, b.z1};
  double t_near = -kInfinity, t_far = kInfinity;
  int near_axis = 0;
  double near_sign = 1.0;
  for (int a = 0; a < 3; ++a) {
    if (std::abs(ld[a]) < 1e-12) {
      if (lo[a] < lower[a] || lo[a] > upper[a]) return false;
      continue;
    }
    const double inv = 1.0 / ld[a];
    double t0 = (lower[a] - lo[a]) * inv, t1 = (upper[a] - lo[a]) * inv;
    double s = -1.0;  // entering through the lower face
    if (t0 > t1) {
      std::swap(t0, t1);
      s = 1.0;
    }
    if (t0 > t_near) {
      t_near = t0;
      near_axis = a;
      near_sign = s;
    }
    t_far = std::min(t_far, t1);
    if (t_near > t_far) return false;
  }
  if (t_near <= t_min || t_near >= t_max) return false;  // behind, beyond, or the origin is inside
  *t_hit = t_near;
  *axis = near_axis;
  *sign = near_sign;
  return true;
}

inline bool IntersectCylinder(const World::Cylinder& c, const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                              double t_min, double t_max, double* t_hit, int* axis) {
  const double ox = o.x() - c.cx, oy = o.y() - c.cy;
  bool found = false;
  const double a = d.x() * d.x() + d.y() * d.y();
  if (a > 1e-12) {
    const double b = ox * d.x() + oy * d.y();
    const double cc = ox * ox + oy * oy - c.radius * c.radius;
    const double disc = b * b - a * cc;
    if (disc >= 0.0) {
      const double t = (-b - std::sqrt(disc)) / a;
      const double z = o.z() + t * d.z();
      if (t > t_min && t < t_max && z >= c.z0 && z <= c.z1) {
        *t_hit = t;
        *axis = 0;
        t_max = t;
        found = true;
      }
    }
  }
  if (d.z() < -1e-12) {  // top cap, seen from above
    const double t = (c.z1 - o.z()) / d.z();
    const double x = ox + t * d.x(), y = oy + t * d.y();
    if (t > t_min && t < t_max && x * x + y * y <= c.radius * c.radius) {
      *t_hit = t;
      *axis = 2;
      found = true;
    }
  }
  return found;
}

inline bool IntersectSphere(const World::Sphere& s, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_min,
                            double t_max, double* t_hit) {
  const double ox = o.x() - s.cx, oy = o.y() - s.cy, oz = o.z() - s.cz;
  const double b = ox * d.x() + oy * d.y() + oz * d.z();
  const double c = ox * ox + oy * oy + oz * oz - s.radius * s.radius;
  const double disc = b * b - c;
  if (disc < 0.0) return false;
  const double t = -b - std::sqrt(disc);
  if (t <= t_min || t >= t_max) return false;
  *t_hit = t;
  return true;
}

// The object grid's placement: cells of cell_size metres from (x0, y0), nx by ny of them.
struct GridFrame {
  double x0, y0, cell_size;
  int nx, ny;
};

// Clips the ray's interval [*t0, *t1] to the slab 0 <= z <= top_z (where
// objects live) and to the grid's rectangle; false when nothing is left.
inline bool ClipToGrid(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double top_z, const GridFrame& grid,
                       double* t0, double* t1) {
  if (std::abs(d.z()) > 1e-12) {
    double ta = (0.0 - o.z()) / d.z(), tb = (top_z - o.z()) / d.z();
    if (ta > tb) std::swap(ta, tb);
    *t0 = std::max(*t0, ta);
    *t1 = std::min(*t1, tb);
  } else if (o.z() < 0.0 || o.z() > top_z) {
    return false;
  }
  const double gx1 = grid.x0 + grid.nx * grid.cell_size, gy1 = grid.y0 + grid.ny * grid.cell_size;
  const double bounds_lo[2] = {grid.x0, grid.y0}, bounds_hi[2] = {gx1, gy1};
  for (int a = 0; a < 2; ++a) {
    if (std::abs(d[a]) < 1e-12) {
      if (o[a] < bounds_lo[a] || o[a] > bounds_hi[a]) return false;
      continue;
    }
    double ta = (bounds_lo[a] - o[a]) / d[a], tb = (bounds_hi[a] - o[a]) / d[a];
    if (ta > tb) std::swap(ta, tb);
    *t0 = std::max(*t0, ta);
    *t1 = std::min(*t1, tb);
  }
  return !(*t0 > *t1);
}

// The grid cells a ray passes through in x and y, in order, from the cell at t0.
struct CellWalk {
  CellWalk(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t0, const GridFrame& grid) {
    const double x = o.x() + t0 * d.x(), y = o.y() + t0 * d.y();
    ix = std::clamp(static_cast<int>(std::floor((x - grid.x0) / grid.cell_size)), 0, grid.nx - 1);
    iy = std::clamp(static_cast<int>(std::floor((y - grid.y0) / grid.cell_size)), 0, grid.ny - 1);
    step_x = d.x() > 0 ? 1 : -1;
    step_y = d.y() > 0 ? 1 : -1;
    delta_x = std::abs(d.x()) > 1e-12 ? grid.cell_size / std::abs(d.x()) : kInfinity;
    delta_y = std::abs(d.y()) > 1e-12 ? grid.cell_size / std::abs(d.y()) : kInfinity;
    next_x = std::abs(d.x()) > 1e-12 ? (grid.x0 + (ix + (step_x > 0 ? 1 : 0)) * grid.cell_size - o.x()) / d.x()
                                     : kInfinity;
    next_y = std::abs(d.y()) > 1e-12 ? (grid.y0 + (iy + (step_y > 0 ? 1 : 0)) * grid.cell_size - o.y()) / d.y()
                                     : kInfinity;
  }

  std::size_t Cell(const GridFrame& grid) const { return static_cast<std::size_t>(iy) * grid.nx + ix; }

  // Into the next cell; false once the ray leaves the grid.
  bool Step(const GridFrame& grid) {
    if (next_x < next_y) {
      ix += step_x;
      next_x += delta_x;
      return !(ix < 0 || ix >= grid.nx);
    }
    iy += step_y;
    next_y += delta_y;
    return !(iy < 0 || iy >= grid.ny);
  }

  int ix, iy;
  int step_x, step_y;
  double delta_x, delta_y;  // ray parameter across one cell in x, y
  double next_x, next_y;    // ray parameter at the next cell boundary in x, y
};

// The last objects a ray tested: objects spanning several cells (buildings,
// pavements) are tested once per ray.
class Mailbox {
 public:
  // True when `ref` was tested already; else remembers it.
  bool TestedBefore(std::uint32_t ref) {
    if (std::find(std::begin(refs_), std::end(refs_), ref) != std::end(refs_)) return true;
    refs_[next_++ & 7u] = ref;
    return false;
  }

 private:
  std::uint32_t refs_[8] = {~0u, ~0u, ~0u, ~0u, ~0u, ~0u, ~0u, ~0u};
  std::uint32_t next_ = 0;
};

struct ObjectHit {
  double t = 0.0;
  int axis = 0;
  double sign = 1.0;
};

inline bool IntersectObject(std::uint32_t kind, std::uint32_t index, const std::vector<World::Box>& boxes,
                            const std::vector<World::Cylinder>& cylinders, const std::vector<World::Sphere>& spheres,
                            const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_min, double t_max,
                            ObjectHit* hit) {
  if (kind == kKindBox) return IntersectBox(boxes[index], o, d, t_min, t_max, &hit->t, &hit->axis, &hit->sign);
  if (kind == kKindCylinder) return IntersectCylinder(cylinders[index], o, d, t_min, t_max, &hit->t, &hit->axis);
  return IntersectSphere(spheres[index], o, d, t_min, t_max, &hit->t);
}

}  // namespace

template <bool kAnyHit>
bool World::Traverse(const Ray& ray, double min_distance, double max_distance, Candidate* best) const {
  const Eigen::Vector3d& o = ray.origin;
  const Eigen::Vector3d& d = ray.direction;
  double t0 = min_distance, t1 = std::min(max_distance, best->t);
  const GridFrame grid{grid_x0_, grid_y0_, cell_size_, grid_nx_, grid_ny_};
  if (!ClipToGrid(o, d, top_z_, grid, &t0, &t1)) return false;

  CellWalk walk(o, d, t0, grid);
  bool found = false;
  double cell_entry = t0;
  Mailbox mailbox;
  for (;;) {
    const std::size_t cell = walk.Cell(grid);
    const double cell_exit_t = std::min({walk.next_x, walk.next_y, t1});
    // Lowest height of the ray inside this cell; skip the cell when it passes above everything there.
    const double lowest_z = o.z() + std::min(cell_entry * d.z(), cell_exit_t * d.z());
    const std::uint32_t end = lowest_z > cell_top_z_[cell] ? cell_object_begin_[cell] : cell_object_begin_[cell + 1];
    for (std::uint32_t k = cell_object_begin_[cell]; k < end; ++k) {
      const std::uint32_t ref = cell_objects_[k];
      if (mailbox.TestedBefore(ref)) continue;
      const std::uint32_t kind = ref >> kKindShift, index = ref & kIndexMask;
      const double limit = std::min(best->t, max_distance);
      ObjectHit hit;
      if (!IntersectObject(kind, index, boxes_, cylinders_, spheres_, o, d, min_distance, limit, &hit)) continue;
      best->t = hit.t;
      best->kind = static_cast<int>(kind);
      best->index = index;
      best->face_axis = hit.axis;
      best->face_sign = hit.sign;
      found = true;
      if constexpr (kAnyHit) return true;
    }
    const double cell_exit = std::min(walk.next_x, walk.next_y);
    if (best->t <= cell_exit || cell_exit >= t1) break;
    cell_entry = cell_exit;
    if (!walk.Step(grid)) break;
  }
  return found;
}

bool World::Occluded(const Ray& ray, double max_distance, double min_distance) const {
  if (ray.direction.z() < 0.0 && ray.origin.z() > 0.0) {
    const double t_ground = -ray.origin.z() / ray.direction.z();
    if (t_ground > min_distance && t_ground < max_distance) return true;
  }
  Candidate best;
  return Traverse<true>(ray, min_distance, max_distance, &best);
}

std::optional<SurfaceHit> World::Intersect(const Ray& ray, double max_distance, double min_distance,
                                           bool with_reflectivity) const {
  Candidate best;
  if (ray.direction.z() < 0.0 && ray.origin.z() > 0.0) {
    const double t_ground = -ray.origin.z() / ray.direction.z();
    if (t_ground > min_distance && t_ground <= max_distance) {
      best.t = t_ground;
      best.kind = 3;
    }
  }
  Traverse<false>(ray, min_distance, max_distance, &best);
  if (best.kind < 0) return std::nullopt;
  SurfaceHit hit;
  hit.distance = best.t;
  hit.point = ray.origin + best.t * ray.direction;
  Appearance(best, with_reflectivity, &hit);
  if (hit.normal.dot(ray.direction) > 0.0) hit.normal = -hit.normal;
  hit.albedo = Clamp01(hit.albedo);
  hit.reflectivity = std::max(0.0, hit.reflectivity);
  return hit;
}

// ---------------------------------------------------------------------------
// Appearance: visible albedo and a separate infrared reflectivity per material

namespace {

struct Shade {
  Material material;
  double albedo;
  double reflectivity;
};

// Road surface at world (x, y): wear, grain, cracked areas.
Shade AsphaltAt(std::uint64_t seed, double x, double y) {
  const double wear = Fbm2(seed + 1, x * 0.12, y * 0.12, 2);
  const double grain = ValueNoise2(seed + 2, x * 9.0, y * 9.0);
  const double fine = ValueNoise2(seed + 3, x * 31.0, y * 31.0);
  double albedo = 0.13 * (1.0 + 0.4 * wear + 0.18 * grain + 0.12 * fine);
  // Binder-rich (dark, smooth) areas scatter the infrared more weakly than worn aggregate.
  double reflectivity = 0.06 + 2.6 * albedo * albedo;
  const double cracked = ValueNoise2(seed + 4, x * 0.07, y * 0.07);
  if (cracked > 0.25) {
    const double crack = ValueNoise2(seed + 5, x * 0.45, y * 0.45);
    if (std::abs(crack) < 0.006) {
      albedo *= 0.45;
      reflectivity *= 0.6;
    }
  }
  return {Material::kAsphalt, albedo, reflectivity};
}

// The decal a ground point lies on, of those listed for its grid cell: the
// topmost (the last added) that covers it.
struct DecalHit {
  std::int64_t index = -1;  // into the world's decals; -1: none covers the point
  double u = 0.0, v = 0.0;  // the point in the decal's frame (m)
};

DecalHit TopDecalAt(const std::vector<World::Decal>& decals, const std::vector<std::uint32_t>& cell_decals,
                    std::uint32_t cell_begin, std::uint32_t cell_end, const Eigen::Vector3d& p) {
  DecalHit hit;
  for (std::uint32_t k = cell_begin; k < cell_end; ++k) {
    const World::Decal& d = decals[cell_decals[k]];
    const double ox = p.x() - d.cx, oy = p.y() - d.cy;
    const double lu = ox * d.cos_yaw + oy * d.sin_yaw, lv = -ox * d.sin_yaw + oy * d.cos_yaw;
    const bool inside = d.is_disc ? (lu * lu + lv * lv <= d.half_u * d.half_u)
                                  : (std::abs(lu) <= d.half_u && std::abs(lv) <= d.half_v);
    if (inside && static_cast<std::int64_t>(cell_decals[k]) > hit.index) {
      hit.index = cell_decals[k];
      hit.u = lu;
      hit.v = lv;
    }
  }
  return hit;
}

// A decal's look at ground point p, over the asphalt shade there; (du, dv) is
// p in the decal's frame (m).
Shade DecalShade(const World::Look& look, const World::Decal& d, const Eigen::Vector3d& p, double du, double dv,
                 const Shade& asphalt) {
  switch (look.material) {
    case Material::kRoadPaint: {
      // Worn paint shows the asphalt through; the paint's glass beads are retro-reflective.
      const double cover = Clamp01(0.8 + 0.6 * Fbm2(look.seed, p.x() * 3.0, p.y() * 3.0, 2));
      return {Material::kRoadPaint, Mix(asphalt.albedo, 0.72, cover), Mix(asphalt.reflectivity, 1.15, cover * cover)};
    }
    case Material::kPatchDark:
      return {Material::kPatchDark, 0.075 * (1.0 + 0.2 * ValueNoise2(look.seed, p.x() * 8, p.y() * 8)),
              0.05 + 0.03 * ValueNoise2(look.seed + 9, p.x() * 3, p.y() * 3)};
    case Material::kPatchConcrete:
      return {Material::kPatchConcrete, 0.3 * (1.0 + 0.15 * Fbm2(look.seed, p.x() * 2, p.y() * 2, 2)),
              0.2 + 0.08 * ValueNoise2(look.seed + 9, p.x() * 2.5, p.y() * 2.5)};
    case Material::kManhole: {
      const bool raised = (static_cast<int>(std::floor(du / 0.05)) + static_cast<int>(std::floor(dv / 0.05))) % 2 == 0;
      const bool rim = std::sqrt(du * du + dv * dv) > d.half_u - 0.04;
      return {Material::kManhole, rim ? 0.25 : (raised ? 0.22 : 0.12), rim ? 0.35 : (raised ? 0.55 : 0.3)};
    }
    default:
      return asphalt;
  }
}

// A point on a box's face: its place in the box's frame and the texture
// coordinates of the face.
struct BoxFacePoint {
  double lu = 0.0, lv = 0.0;       // horizontal, from the box centre along u and v (m)
  double lz = 0.0;                 // height (m)
  double tex_u = 0.0, tex_v = 0.0;  // on the face (m)
  Eigen::Vector3d normal;          // world, unit, outwards
};

BoxFacePoint BoxFaceAt(const World::Box& b, int face_axis, double face_sign, const Eigen::Vector3d& p) {
  BoxFacePoint face;
  const double ox = p.x() - b.cx, oy = p.y() - b.cy;
  face.lu = ox * b.cos_yaw + oy * b.sin_yaw;
  face.lv = -ox * b.sin_yaw + oy * b.cos_yaw;
  face.lz = p.z();
  if (face_axis == 0) {
    face.normal = Eigen::Vector3d(face_sign * b.cos_yaw, face_sign * b.sin_yaw, 0.0);
    face.tex_u = face.lv;
    face.tex_v = face.lz;
  } else if (face_axis == 1) {
    face.normal = Eigen::Vector3d(-face_sign * b.sin_yaw, face_sign * b.cos_yaw, 0.0);
    face.tex_u = face.lu + b.u_offset;
    face.tex_v = face.lz;
  } else {
    face.normal = Eigen::Vector3d(0.0, 0.0, face_sign);
    face.tex_u = face.lu + b.u_offset;
    face.tex_v = face.lv;
  }
  return face;
}

// Pavement slabs, with the kerb stones along the road edge.
Shade PavingShade(const World::Look& look, const World::Box& b, int face_axis, const BoxFacePoint& face) {
  const double a0 = look.albedo;
  const double tex_u = face.tex_u, lv = face.lv, lz = face.lz;
  const bool kerb_strip = face_axis != 2 || look.param * lv > b.half_v - 0.15;
  if (kerb_strip) {
    const double speckle = ValueNoise2(look.seed, tex_u * 40.0, (face_axis == 2 ? lv : lz) * 40.0);
    const bool joint = Fract(tex_u / 0.9) < 0.012;
    const double albedo = joint ? 0.12 : 0.38 + 0.08 * speckle;
    return {Material::kKerb, albedo, joint ? 0.15 : 0.22 + 0.5 * std::pow(0.5 + 0.5 * speckle, 2.0)};
  }
  const double across = lv + b.half_v;
  const double fu = Fract(tex_u / 0.6), fv = Fract(across / 0.6);
  if (fu < 0.02 || fv < 0.02) return {Material::kPaving, 0.1, 0.16};
  const auto iu = static_cast<std::int64_t>(std::floor(tex_u / 0.6));
  const auto iv = static_cast<std::int64_t>(std::floor(across / 0.6));
  const double h1 = HashUnit(look.seed, iu, iv), h2 = HashUnit(look.seed + 1, iu, iv);
  const double albedo = a0 + 0.12 * (h1 - 0.5) + 0.04 * ValueNoise2(look.seed + 2, tex_u * 12, lv * 12) +
                        0.05 * Fbm2(look.seed + 3, tex_u * 0.4, lv * 0.4, 2);
  // Slabs from different batches: infrared only loosely tied to the visible shade.
  return {Material::kPaving, albedo, 0.34 + 0.3 * (h2 - 0.5) + 0.6 * (albedo - a0)};
}

// A facade's door, plinth or window at (u along the face from the box
// centre, lz up), m; nothing where the wall itself shows.
std::optional<Shade> FacadeFeatureShade(const World::Look& look, const World::Box& b, const World::Facade& f, double u,
                                        double lz) {
  if (u >= f.door_u && u <= f.door_u + f.door_width && lz <= f.door_height) {
    const bool frame = u < f.door_u + 0.08 || u > f.door_u + f.door_width - 0.08 || lz > f.door_height - 0.08;
    const double door_albedo = 0.05 + 0.5 * HashUnit(look.seed, 5);
    return frame ? Shade{Material::kWindowFrame, f.frame_albedo, f.frame_ir}
                 : Shade{Material::kDoor, door_albedo + 0.03 * ValueNoise2(look.seed, u * 20, lz * 2),
                         0.3 + 0.4 * HashUnit(look.seed, 6)};
  }
  if (lz < f.plinth_height) {
    const double speckle = ValueNoise2(look.seed + 7, u * 25, lz * 25);
    return Shade{Material::kStone, 0.3 + 0.06 * speckle, 0.42 + 0.1 * speckle};
  }
  const double floor_index = std::floor(lz / f.floor_height);
  const double v_in = lz - floor_index * f.floor_height;
  const double m = Fract((u - f.window_offset) / f.window_spacing) * f.window_spacing;
  const bool near_door = floor_index == 0 && u > f.door_u - 0.5 && u < f.door_u + f.door_width + 0.5;
  const bool in_window = !near_door && v_in >= f.sill_height && v_in <= f.sill_height + f.window_height &&
                         m <= f.window_width && std::abs(u) < b.half_u - 0.4;
  if (!in_window) return std::nullopt;
  const double wv = v_in - f.sill_height;
  const bool frame = m < 0.07 || m > f.window_width - 0.07 || wv < 0.07 || wv > f.window_height - 0.07 ||
                     std::abs(m - 0.5 * f.window_width) < 0.03;
  if (frame) return Shade{Material::kWindowFrame, f.frame_albedo, f.frame_ir};
  // Reflections of the opposite street in the glass.
  const double reflection = 0.5 + 0.5 * ValueNoise2(look.seed + 8, u * 0.8, lz * 1.5);
  return Shade{Material::kGlass, 0.04 + 0.12 * reflection, 0.02};
}

// Brick courses and mortar at (u along the face from the box centre, lz up),
// m, seen from `distance` m away.
Shade BrickShade(const World::Look& look, const World::Box& b, double u, double lz, double distance) {
  const double a0 = look.albedo;
  const double course = std::floor(lz / 0.075);
  const double offset = std::fmod(course, 2.0) * 0.1125;
  const double bu = (u + b.u_offset + offset) / 0.225;
  const bool mortar = Fract(bu) < 0.045 || Fract(lz / 0.075) < 0.13;
  const Shade mortar_shade{Material::kBrick, 0.45, 0.28};
  const auto bi = static_cast<std::int64_t>(std::floor(bu)), ci = static_cast<std::int64_t>(course);
  const double h1 = HashUnit(look.seed, bi, ci), h2 = HashUnit(look.seed + 1, bi, ci);
  const double soot = 0.5 + 0.5 * Fbm2(look.seed + 2, u * 0.3, lz * 0.3, 2);
  const double albedo = a0 * (1.0 + 0.35 * (h1 - 0.5)) * (0.75 + 0.35 * soot);
  // Fired clay is bright in the near infrared, brighter than its mortar.
  const Shade brick_shade{Material::kBrick, albedo, look.ir_gain * (0.5 + 0.3 * (h2 - 0.5)) + 0.25 * (albedo - a0)};
  Shade shade = mortar ? mortar_shade : brick_shade;
  // Far away a pixel (or a lidar footprint) covers several joints: average the
  // pattern (17 % mortar) instead of aliasing it into moire.
  const double blend = std::clamp((distance * kPixelAngle - 0.004) / 0.012, 0.0, 1.0);
  if (blend > 0.0) {
    shade.albedo = Mix(shade.albedo, 0.83 * brick_shade.albedo + 0.17 * mortar_shade.albedo, blend);
    shade.reflectivity =
        Mix(shade.reflectivity, 0.83 * brick_shade.reflectivity + 0.17 * mortar_shade.reflectivity, blend);
  }
  return shade;
}

// Painted render at (u along the face from the box centre, lz up), m.
Shade PlasterShade(const World::Look& look, double u, double lz) {
  const double a0 = look.albedo;
  const double stain = Fbm2(look.seed + 3, u * 0.5, lz * 0.5, 3);
  const double albedo = a0 * (1.0 + 0.1 * stain + 0.03 * ValueNoise2(look.seed + 4, u * 15, lz * 15)) -
                        0.06 * std::max(0.0, ValueNoise2(look.seed + 5, u * 2.0, lz * 0.15));
  return {Material::kPlaster, albedo, look.ir_gain * (0.12 + 0.9 * albedo * albedo * albedo)};
}

// A brick or plaster building: stone roof; the facade's doors, plinth and
// windows on the street side (face v); the wall elsewhere.
Shade BuildingShade(const World::Look& look, const World::Box& b, const std::vector<World::Facade>& facades,
                    int face_axis, const BoxFacePoint& face, double distance) {
  if (face_axis == 2) return {Material::kStone, 0.1, 0.1};  // roof
  const double u = face_axis == 1 ? face.lu : face.lv;  // along the face, from the box centre
  if (face_axis == 1 && look.facade >= 0) {
    const World::Facade& facade = facades[static_cast<std::size_t>(look.facade)];
    if (const std::optional<Shade> feature = FacadeFeatureShade(look, b, facade, u, face.lz)) return *feature;
  }
  return look.material == Material::kBrick ? BrickShade(look, b, u, face.lz, distance)
                                           : PlasterShade(look, u, face.lz);
}

// Tree crowns and hedges at world point p (3D noise: no face to texture).
Shade FoliageAt(const World::Look& look, const Eigen::Vector3d& p) {
  const double n1 = ValueNoise3(look.seed, p.x() * 3.5, p.y() * 3.5, p.z() * 3.5);
  const double n2 = ValueNoise3(look.seed + 1, p.x() * 11, p.y() * 11, p.z() * 11);
  double albedo = look.albedo + 0.05 * n1 + 0.03 * n2;
  double reflectivity = look.ir_gain * (0.6 + 0.15 * ValueNoise3(look.seed + 2, p.x() * 2, p.y() * 2, p.z() * 2));
  if (n1 < -0.5) {  // gaps between leaves
    albedo *= 0.4;
    reflectivity *= 0.5;
  }
  return {Material::kVegetation, albedo, reflectivity};
}

// The infrared noise texture coordinates (m) of foliage at world point p.
void FoliageTexture(const Eigen::Vector3d& p, double* tex_u, double* tex_v) {
  *tex_u = p.x() + p.z();
  *tex_v = p.y() - p.z();
}

// A box face point's look by its material. Foliage has no face texture: its
// texture coordinates in *face are replaced by FoliageTexture's.
Shade BoxShade(const World::Look& look, const World::Box& b, const std::vector<World::Facade>& facades, int face_axis,
               const Eigen::Vector3d& p, double distance, BoxFacePoint* face) {
  const double a0 = look.albedo;
  const double tex_u = face->tex_u, tex_v = face->tex_v, lu = face->lu, lv = face->lv, lz = face->lz;
  switch (look.material) {
    case Material::kPaving:
      return PavingShade(look, b, face_axis, *face);
    case Material::kBrick:
    case Material::kPlaster:
      return BuildingShade(look, b, facades, face_axis, *face, distance);
    case Material::kGrass: {
      if (face_axis != 2) return {Material::kStone, 0.3, 0.35};
      const double n1 = ValueNoise2(look.seed, p.x() * 6, p.y() * 6);
      return {Material::kGrass, 0.13 + 0.035 * n1 + 0.02 * ValueNoise2(look.seed + 1, p.x() * 25, p.y() * 25),
              0.55 + 0.12 * ValueNoise2(look.seed + 2, p.x() * 2, p.y() * 2)};
    }
    case Material::kStone: {
      const double speckle = ValueNoise2(look.seed, tex_u * 20, tex_v * 20);
      const double block = HashUnit(look.seed, static_cast<std::int64_t>(std::floor(tex_u / 0.4)),
                                    static_cast<std::int64_t>(std::floor(tex_v / 0.25)));
      const double albedo = a0 * (0.8 + 0.4 * block) + 0.05 * speckle;
      // Non-monotonic: mid-grey stone is the brightest in the infrared.
      return {Material::kStone, albedo, 0.5 - 0.9 * std::abs(albedo - 0.33) + 0.05 * speckle};
    }
    case Material::kVegetation:
      FoliageTexture(p, &face->tex_u, &face->tex_v);
      return FoliageAt(look, p);
    case Material::kMetal:
      return {Material::kMetal, a0 * (1.0 + 0.1 * ValueNoise2(look.seed, tex_u * 5, tex_v * 5)), look.ir_gain * 0.35};
    case Material::kSign: {
      if (face_axis != 0) return {Material::kMetal, 0.3, 0.3};
      const bool border = std::abs(lv) > b.half_v - 0.05 || lz < b.z0 + 0.05 || lz > b.z1 - 0.05;
      return border ? Shade{Material::kSign, 0.8, 1.2} : Shade{Material::kSign, a0, 0.9 * look.ir_gain};
    }
    case Material::kCarPaint: {
      if (lz < look.param + 0.16) return {Material::kTyre, 0.06, 0.08};  // bumper and sills
      const double dirt = ValueNoise2(look.seed, tex_u * 3, tex_v * 3);
      return {Material::kCarPaint, a0 * (1.0 + 0.06 * dirt), look.ir_gain * (0.2 + 0.25 * a0) + 0.02 * dirt};
    }
    case Material::kCarGlass: {
      const bool pillar = face_axis == 2 || std::abs(lu) > b.half_u - 0.12;
      return pillar ? Shade{Material::kCarPaint, a0, look.ir_gain * (0.2 + 0.25 * a0)}
                    : Shade{Material::kCarGlass, 0.05 + 0.06 * (0.5 + 0.5 * ValueNoise2(look.seed, tex_u, tex_v * 3)),
                            0.04};
    }
    case Material::kTyre:
      return {Material::kTyre, 0.05, 0.07};
    default:
      return {look.material, a0, 0.3};
  }
}

}  // namespace

void World::Appearance(const Candidate& c, bool with_reflectivity, SurfaceHit* out) const {
  const Eigen::Vector3d& p = out->point;
  Shade shade{Material::kAsphalt, 0.1, 0.1};
  // Texture coordinates (m) on the surface, for the infrared noise texture.
  double tex_u = p.x(), tex_v = p.y();
  std::uint64_t look_seed = seed_;

  if (c.kind == 3) {  // ground: asphalt, unless a decal covers the point
    out->normal = Eigen::Vector3d::UnitZ();
    out->object = 0;
    shade = AsphaltAt(seed_, p.x(), p.y());
    const int ix = static_cast<int>(std::floor((p.x() - grid_x0_) / cell_size_));
    const int iy = static_cast<int>(std::floor((p.y() - grid_y0_) / cell_size_));
    if (ix >= 0 && ix < grid_nx_ && iy >= 0 && iy < grid_ny_) {
      const std::size_t cell = static_cast<std::size_t>(iy) * grid_nx_ + ix;
      const DecalHit decal =
          TopDecalAt(decals_, cell_decals_, cell_decal_begin_[cell], cell_decal_begin_[cell + 1], p);
      if (decal.index >= 0) {
        const Decal& d = decals_[static_cast<std::size_t>(decal.index)];
        const Look& look = looks_[d.look];
        out->object =
            static_cast<std::uint32_t>(1 + boxes_.size() + cylinders_.size() + spheres_.size() + decal.index);
        look_seed = look.seed;
        shade = DecalShade(look, d, p, decal.u, decal.v, shade);
      }
    }
  } else if (c.kind == 0) {
    const Box& b = boxes_[c.index];
    const Look& look = looks_[b.look];
    look_seed = look.seed;
    out->object = 1 + c.index;
    BoxFacePoint face = BoxFaceAt(b, c.face_axis, c.face_sign, p);
    out->normal = face.normal;
    shade = BoxShade(look, b, facades_, c.face_axis, p, out->distance, &face);
    tex_u = face.tex_u;
    tex_v = face.tex_v;
  } else if (c.kind == 1) {
    const Cylinder& cyl = cylinders_[c.index];
    const Look& look = looks_[cyl.look];
    look_seed = look.seed;
    out->object = static_cast<std::uint32_t>(1 + boxes_.size() + c.index);
    if (c.face_axis == 0) {
      out->normal = Eigen::Vector3d(p.x() - cyl.cx, p.y() - cyl.cy, 0.0).normalized();
      tex_u = std::atan2(p.y() - cyl.cy, p.x() - cyl.cx) * cyl.radius;
      tex_v = p.z();
    } else {
      out->normal = Eigen::Vector3d::UnitZ();
    }
    if (look.material == Material::kBark) {
      shade = {Material::kBark, look.albedo + 0.05 * ValueNoise2(look.seed, tex_u * 15, tex_v * 1.5),
               0.3 + 0.1 * ValueNoise2(look.seed + 1, tex_u * 4, tex_v * 2)};
    } else {
      shade = {look.material, look.albedo * (1.0 + 0.1 * ValueNoise2(look.seed, tex_u * 5, tex_v * 5)),
               look.ir_gain * 0.35};
    }
  } else {
    const Sphere& s = spheres_[c.index];
    const Look& look = looks_[s.look];
    look_seed = look.seed;
    out->object = static_cast<std::uint32_t>(1 + boxes_.size() + cylinders_.size() + c.index);
    out->normal = Eigen::Vector3d(p.x() - s.cx, p.y() - s.cy, p.z() - s.cz) / s.radius;
    shade = FoliageAt(look, p);
    FoliageTexture(p, &tex_u, &tex_v);
  }
  // A separate infrared noise texture, independent of the visible texture.
  out->material = shade.material;
  out->albedo = shade.albedo;
  out->reflectivity = shade.reflectivity;
  if (with_reflectivity) {
    const double ir_noise = Fbm2(look_seed ^ 0x1F2E3D4C5B6A7988ULL, tex_u * 1.7, tex_v * 1.7, 2);
    out->reflectivity *= std::exp(0.3 * ir_noise);
  }
}

template bool World::Traverse<true>(const Ray&, double, double, Candidate*) const;
template bool World::Traverse<false>(const Ray&, double, double, Candidate*) const;

}  // namespace scenecal::sim
