// The vectorised kernels of SceneSwathe (core/swathe.hpp), in swathe_kernels.cpp:
// block projection, hard counts, B-spline samples and their gradient. Each
// hot loop is compiled twice and chosen at run time (target_clones: AVX2 and
// baseline x86-64, both without FMA, so both give bit-identical results).
#pragma once

#include <cstdint>
#include <span>

#include <Eigen/Core>

#include "core/camera_kernel.hpp"

namespace scenecal::swathe_detail {

// Points are projected in blocks: a branch-free pass the compiler vectorises
// (transform, projection, bounds; the same float arithmetic as ProjectFast, so
// the same pixels), then a pass over the accepted points only that calls the
// visitor, prefetching the image rows of a point a few places ahead (the
// bilinear gathers, not the arithmetic, bound the cost kernel).
constexpr int kBlock = 256;
constexpr int kPrefetchDistance = 16;

// Projects count points (x, y, z: lidar frame, metres) under m (3x4,
// T_camerak_lidar) with the camera model of params: pixels u_out, v_out,
// camera depth depth_out (metres) and accepted[k] = 1 when point k projects
// inside params' bounds and visible[k] != 0, else 0. The pinhole and radtan
// models go through a branch-free vectorised loop, the equidistant model
// (an atan per point) through the scalar ProjectFast.
void ProjectAnyBlock(const ProjectionParams& params, const Eigen::Matrix<float, 3, 4>& m, const float* __restrict x,
                     const float* __restrict y, const float* __restrict z, const std::uint8_t* __restrict visible,
                     int count, float* __restrict u_out, float* __restrict v_out, float* __restrict depth_out,
                     std::int32_t* __restrict accepted);

// True when every value is finite and small enough for the hard-count
// kernel's integer bins (SceneSwathe::AddHardCounts' fast path).
bool AllBounded(std::span<const float> values);

}  // namespace scenecal::swathe_detail
