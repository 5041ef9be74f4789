// A procedural street world for the simulator, and the ray caster that the
// camera renderer and the lidar model share.
//
// World frame W: x, y horizontal, z up (metres); the road surface is z = 0.
// The street follows a gently curving centre line parameterised by arc length
// s (metres); a lateral offset d (metres) is positive to the left of the
// direction of increasing s.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace scenecal::sim {

enum class Material : std::uint8_t {
  kAsphalt,        // road surface (the ground plane), with wear, patches and cracks
  kRoadPaint,      // lane markings and crossings, retro-reflective in the infrared
  kPatchDark,      // fresh asphalt repair
  kPatchConcrete,  // concrete repair
  kManhole,        // cast-iron cover
  kPaving,         // pavement slabs, with the kerb along the road edge
  kKerb,           // granite kerb stones
  kBrick,          // brick facade with mortar joints and windows
  kPlaster,        // painted render facade with windows
  kGlass,          // windows: dark, weak infrared return
  kWindowFrame,
  kDoor,
  kVegetation,     // tree crowns and hedges: dark in the visible, bright in the infrared
  kGrass,
  kBark,
  kMetal,          // poles, lamp heads, bins, sign posts
  kSign,           // sign plates: bright paint, very bright retro-reflection
  kCarPaint,       // per-car colour, infrared response not tied to the colour
  kCarGlass,
  kTyre,           // tyres and bumpers
  kStone,          // garden walls and plinths
  kCount
};
const char* MaterialName(Material material);

struct Ray {
  Eigen::Vector3d origin;     // world (m)
  Eigen::Vector3d direction;  // world, unit length
};

struct SurfaceHit {
  double distance = 0.0;        // along the ray (m)
  Eigen::Vector3d point;        // world (m)
  Eigen::Vector3d normal;       // world, unit, facing the ray's origin
  Material material = Material::kAsphalt;
  double albedo = 0.0;          // visible diffuse albedo in [0, 1]
  double reflectivity = 0.0;    // near-infrared reflectivity the lidar sees, in [0, ~1.2]
  std::uint32_t object = 0;     // object id; 0 is the ground
};

// The street's centre line, sampled every kStep metres of arc length.
class CentreLine {
 public:
  CentreLine() = default;
  // Gentle curves from the seed: curvature a sum of long sinusoids, at most
  // about 1/110 m^-1. Covers s in [s_begin, s_end].
  CentreLine(std::uint64_t seed, double s_begin, double s_end);

  Eigen::Vector2d Position(double s) const;  // world xy (m)
  double Heading(double s) const;            // rad, counter-clockwise from world x
  double Curvature(double s) const;          // 1/m, positive turning left
  Eigen::Vector2d Tangent(double s) const;
  Eigen::Vector2d LeftNormal(double s) const;
  // Street coordinates (s, d) -> world xy.
  Eigen::Vector2d ToWorld(double s, double d) const { return Position(s) + d * LeftNormal(s); }
  double s_begin() const { return s_begin_; }
  double s_end() const { return s_end_; }

  static constexpr double kStep = 0.25;  // m

 private:
  double s_begin_ = 0.0, s_end_ = 0.0;
  std::vector<double> heading_;  // rad, at s_begin + i * kStep
  std::vector<Eigen::Vector2d> position_;
  std::vector<double> curvature_;
};

// Cross-section of the street (metres, lateral offsets from the centre line).
struct StreetLayout {
  double road_half_width = 5.5;  // kerb line; includes a parking strip on each side
  double lane_line_offset = 3.4;  // solid line between the driving lane and the parking strip
  double pavement_width_left = 3.0;
  double pavement_width_right = 3.0;
  double kerb_height = 0.13;
  double driving_lane_offset = 1.7;  // centre of the (left-hand) driving lane
};

class World {
 public:
  // Builds the street world for s in [s_begin, s_end] (metres of arc length).
  static World Generate(std::uint64_t seed, double s_begin, double s_end);

  // Nearest surface along the ray within (min_distance, max_distance], with
  // its appearance; nullopt when the ray escapes (sky). Without
  // with_reflectivity the infrared noise texture is skipped (the camera does
  // not need it) and `reflectivity` is left without it.
  std::optional<SurfaceHit> Intersect(const Ray& ray, double max_distance, double min_distance = 1e-4,
                                      bool with_reflectivity = true) const;
  // True when any surface lies along the ray within (min_distance, max_distance).
  bool Occluded(const Ray& ray, double max_distance, double min_distance = 1e-4) const;

  const CentreLine& centre_line() const { return centre_line_; }
  const StreetLayout& layout() const { return layout_; }
  // Unit vector towards the sun (world).
  const Eigen::Vector3d& sun_direction() const { return sun_direction_; }
  std::size_t ObjectCount() const;
  std::uint64_t seed() const { return seed_; }

  // Object storage (public for the generator in world.cpp; treat as read-only).
  struct Look {
    Material material = Material::kAsphalt;
    float albedo = 0.3f;   // base albedo of the object
    float ir_gain = 1.0f;  // object-specific infrared factor
    float param = 0.0f;    // material-specific (kerb side, u offset, ...)
    std::uint32_t seed = 0;
    int facade = -1;       // index into facades_ for buildings
  };
  struct Facade {
    double floor_height, window_width, window_height, sill_height, window_spacing, window_offset;
    double door_u, door_width, door_height, plinth_height;
    double frame_albedo, frame_ir;
  };
  struct Box {  // oriented about the vertical: u along (cos, sin), v to its left
    double cx, cy, z0, z1, half_u, half_v, cos_yaw, sin_yaw;
    double u_offset;  // texture coordinate of the box centre along u (m)
    std::uint32_t look;
  };
  struct Cylinder {  // vertical
    double cx, cy, radius, z0, z1;
    std::uint32_t look;
  };
  struct Sphere {
    double cx, cy, cz, radius;
    std::uint32_t look;
  };
  struct Decal {  // on the road surface z = 0: a rectangle, or a disc when is_disc
    double cx, cy, half_u, half_v, cos_yaw, sin_yaw;
    double u_offset;
    bool is_disc;
    std::uint32_t look;
  };

 private:
  struct Candidate;
  template <bool kAnyHit>
  bool Traverse(const Ray& ray, double min_distance, double max_distance, Candidate* best) const;
  void BuildGrid();
  std::uint32_t AddLook(const Look& look);
  void Appearance(const Candidate& hit, bool with_reflectivity, SurfaceHit* out) const;

  std::uint64_t seed_ = 0;
  CentreLine centre_line_;
  StreetLayout layout_;
  Eigen::Vector3d sun_direction_ = Eigen::Vector3d::UnitZ();
  std::vector<Look> looks_;
  std::vector<Facade> facades_;
  std::vector<Box> boxes_;
  std::vector<Cylinder> cylinders_;
  std::vector<Sphere> spheres_;
  std::vector<Decal> decals_;
  double top_z_ = 0.0;  // highest point of any object (m)

  // Uniform 2D grid over world xy; each cell lists its objects (kind in the
  // top 2 bits, index below) and, separately, the road decals over it.
  double grid_x0_ = 0, grid_y0_ = 0, cell_size_ = 3.0;
  int grid_nx_ = 0, grid_ny_ = 0;
  std::vector<std::uint32_t> cell_object_begin_, cell_objects_;
  std::vector<float> cell_top_z_;  // highest object point over each cell (m): rays above it skip the cell
  std::vector<std::uint32_t> cell_decal_begin_, cell_decals_;

  friend class WorldBuilder;
};

}  // namespace scenecal::sim
