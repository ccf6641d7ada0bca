// skintune: the "candy wrapper", linear blend skinning's best-known failure
// and the reason dual-quaternion skinning exists (Kavan et al. 2007).
//
// A tube along x from 0 to 2, radius 0.25, bound to two joints: joint 0 holds
// x <= 0.5, joint 1 x >= 1.5, and the weights cross linearly between (0.5 each
// at x = 1). Joint 1 twists by an angle about the tube's own axis. Linear
// blending averages the two joints' matrices, so the ring at x = 1 shrinks to
// |cos(angle / 2)| of its radius and collapses to a line at 180 degrees;
// dual quaternions blend the rigid motions and keep it round. Both are the
// float64 golds (SkinGold, SkinGoldDualQuaternion), so these are the
// algorithms' own results, not a kernel's.
#pragma once

#include <vector>

#include "model/mesh.h"

namespace skintune::internal {

struct CandyWrapperPoint {
  double twist_degrees = 0.0;
  double linear_radius = 1.0;      // the middle ring's mean radius under linear blending / the rest radius
  double dual_quaternion_radius = 1.0;  // the same under dual quaternions
  double linear_volume = 1.0;      // the tube's volume between x = 0.5 and 1.5 (rings' areas) / rest
  double dual_quaternion_volume = 1.0;
};

// The tube (rings of 32 vertices every 0.05 along x), two joints.
SkinnedMesh CandyWrapperMesh();

// One point per twist angle, in degrees.
std::vector<CandyWrapperPoint> CandyWrapper(const std::vector<double>& twist_degrees);

}  // namespace skintune::internal
