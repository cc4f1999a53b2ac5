// One shoot-and-bounce ray as the shooter follows it: its branches, the
// chain of reflections they share, and what a hit gives every branch that
// leaves it.
#pragma once

#include <cstdint>
#include <vector>

#include "em/field.hpp"
#include "tracer/solver.hpp"

namespace raysweep::tracer {

// A ray's reflections so far, as links into the ray's chain (the states of
// one ray share their prefixes): copying whole face and point arrays of
// kMaxDepth entries per state cost more than the rest of the loop.
struct Link {
  FaceRef face;
  Vec3 point;
  std::int32_t parent;
};

// One branch of a ray: a segment's origin and direction, what it went
// through so far.
struct RayState {
  Vec3 o, d;
  double len;
  int transmissions;
  double loss_db;
  bool has_leaving;
  FaceRef leaving;
  int n;               // reflections so far
  std::int32_t last;   // the last one's link (-1: none)
  // Diffuse bookkeeping: the ray tube's field (transmit pattern times
  // every coefficient so far), dL/dt of the legs so far, the velocity of
  // the last interaction point.
  CVec3 field;
  double dl_dt;
  Vec3 v_prev;
};

// The faces of st's reflections (links into `chain`) in order into out[0, st.n), their points
// into points (when given).
inline void unwind(const std::vector<Link>& chain, const RayState& st, FaceRef* out, Vec3* points) {
  std::int32_t l = st.last;
  for (int k = st.n - 1; k >= 0; --k, l = chain[l].parent) {
    out[k] = chain[l].face;
    if (points) points[k] = chain[l].point;
  }
}

// What one hit gives every branch leaving it: the face's plane and
// material, the mirror direction and, with diffuse on, the ray tube's
// slab coefficients, the field a smooth surface would reflect and dL/dt.
struct HitField {
  const Hit* hit;
  Vec3 p;
  std::uint16_t mat;
  const RadioMaterial* material;
  double s_coef;
  Plane plane;
  Vec3 k_out;
  SlabCoefficients coef{};
  Vec3 es{0, 0, 0}, ep_in{0, 0, 0}, v_surf{0, 0, 0};
  CVec3 e_ref{};
  double dl_in = 0;
};

}  // namespace raysweep::tracer
