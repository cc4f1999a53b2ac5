#include "meshkit/footprint.hpp"

#include <CGAL/Arr_segment_traits_2.h>
#include <CGAL/Arrangement_2.h>
#include <CGAL/Boolean_set_operations_2.h>
#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_exact_constructions_kernel.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_2.h>
#include <CGAL/Polygon_set_2.h>
#include <CGAL/Polygon_with_holes_2.h>
#include <CGAL/Polyline_simplification_2/simplify.h>
#include <CGAL/Triangulation_face_base_with_info_2.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <map>

namespace raysweep::meshkit {

namespace {

using EK = CGAL::Exact_predicates_exact_constructions_kernel;
using IK = CGAL::Exact_predicates_inexact_constructions_kernel;
using EPolygon = CGAL::Polygon_2<EK>;
using EPolygonWH = CGAL::Polygon_with_holes_2<EK>;
using EPolygonSet = CGAL::Polygon_set_2<EK>;
using IPolygon = CGAL::Polygon_2<IK>;
using IPolygonWH = CGAL::Polygon_with_holes_2<IK>;

std::vector<Vec2> clean_ring(const std::vector<Vec2>& ring, double tol, int& removed) {
  std::vector<Vec2> out;
  out.reserve(ring.size());
  const double tol2 = tol * tol;
  auto close = [tol2](const Vec2& a, const Vec2& b) {
    const double dx = a[0] - b[0], dy = a[1] - b[1];
    return dx * dx + dy * dy <= tol2;
  };
  for (const Vec2& p : ring) {
    if (!out.empty() && close(out.back(), p)) {
      ++removed;
      continue;
    }
    out.push_back(p);
  }
  // The closing node of an OSM ring repeats the first one; it is not a duplicate.
  if (out.size() > 1 && close(out.front(), out.back())) out.pop_back();
  return out;
}

EPolygon to_exact(const std::vector<Vec2>& ring) {
  EPolygon p;
  for (const Vec2& v : ring) p.push_back(EK::Point_2(v[0], v[1]));
  return p;
}

// Even-odd interior of a ring that may cross or overlap itself, as simple
// polygons with holes: the regions of the arrangement of its edges that an
// odd number of edges separates from infinity.
std::vector<EPolygonWH> even_odd_regions(const EPolygon& ring) {
  using Traits = CGAL::Arr_segment_traits_2<EK>;
  using Arrangement = CGAL::Arrangement_2<Traits>;
  std::vector<Traits::Curve_2> segments;
  for (auto e = ring.edges_begin(); e != ring.edges_end(); ++e)
    if (!e->is_degenerate()) segments.emplace_back(e->source(), e->target());
  Arrangement arr;
  CGAL::insert(arr, segments.begin(), segments.end());

  // Crossing an arrangement edge flips parity once per input segment over it
  // (overlapping back-and-forth segments cancel).
  auto multiplicity = [&](Arrangement::Halfedge_const_handle h) {
    const EK::Point_2 mid = CGAL::midpoint(h->source()->point(), h->target()->point());
    int n = 0;
    for (auto e = ring.edges_begin(); e != ring.edges_end(); ++e)
      if (!e->is_degenerate() && e->has_on(mid)) ++n;
    return n;
  };
  std::map<Arrangement::Face_const_handle, int> parity;
  std::deque<Arrangement::Face_const_handle> queue;
  parity[arr.unbounded_face()] = 0;
  queue.push_back(arr.unbounded_face());
  auto visit_ccb = [&](Arrangement::Ccb_halfedge_const_circulator start, int p) {
    auto c = start;
    do {
      auto nb = c->twin()->face();
      if (!parity.count(nb)) {
        parity[nb] = (p + multiplicity(c)) % 2;
        queue.push_back(nb);
      }
    } while (++c != start);
  };
  while (!queue.empty()) {
    auto f = queue.front();
    queue.pop_front();
    const int p = parity[f];
    if (!f->is_unbounded()) visit_ccb(f->outer_ccb(), p);
    for (auto h = f->inner_ccbs_begin(); h != f->inner_ccbs_end(); ++h) visit_ccb(*h, p);
  }

  auto ccb_polygon = [](Arrangement::Ccb_halfedge_const_circulator start) {
    EPolygon poly;
    auto c = start;
    do {
      // Antennas (edges with the same face on both sides) bound no area.
      if (c->twin()->face() != c->face()) poly.push_back(c->source()->point());
    } while (++c != start);
    return poly;
  };
  std::vector<EPolygonWH> regions;
  for (auto f = arr.faces_begin(); f != arr.faces_end(); ++f) {
    if (f->is_unbounded() || parity[f] != 1) continue;
    EPolygon outer = ccb_polygon(f->outer_ccb());
    if (outer.size() < 3) continue;
    if (outer.orientation() == CGAL::CLOCKWISE) outer.reverse_orientation();
    EPolygonWH pwh(outer);
    for (auto h = f->inner_ccbs_begin(); h != f->inner_ccbs_end(); ++h) {
      EPolygon hole = ccb_polygon(*h);
      if (hole.size() < 3) continue;
      if (hole.orientation() == CGAL::COUNTERCLOCKWISE) hole.reverse_orientation();
      pwh.add_hole(hole);
    }
    regions.push_back(std::move(pwh));
  }
  return regions;
}

// A ring as a polygon set: simple rings directly, others by the even-odd rule.
EPolygonSet ring_set(const EPolygon& ring, FootprintRepairs& repairs) {
  EPolygonSet set;
  if (ring.size() < 3) return set;
  if (ring.is_simple()) {
    EPolygon p = ring;
    if (p.orientation() == CGAL::COLLINEAR) return set;
    if (p.orientation() == CGAL::CLOCKWISE) p.reverse_orientation();
    set.insert(p);
    return set;
  }
  repairs.self_intersection = true;
  for (const EPolygonWH& r : even_odd_regions(ring)) set.join(r);
  return set;
}

Polygon2 to_double(const EPolygonWH& p) {
  Polygon2 out;
  for (auto v = p.outer_boundary().vertices_begin(); v != p.outer_boundary().vertices_end(); ++v)
    out.outer.push_back({CGAL::to_double(v->x()), CGAL::to_double(v->y())});
  for (auto h = p.holes_begin(); h != p.holes_end(); ++h) {
    std::vector<Vec2> ring;
    for (auto v = h->vertices_begin(); v != h->vertices_end(); ++v)
      ring.push_back({CGAL::to_double(v->x()), CGAL::to_double(v->y())});
    out.holes.push_back(std::move(ring));
  }
  return out;
}

IPolygon to_inexact(const std::vector<Vec2>& ring) {
  IPolygon p;
  for (const Vec2& v : ring) p.push_back(IK::Point_2(v[0], v[1]));
  return p;
}

std::vector<Vec2> from_inexact(const IPolygon& p) {
  std::vector<Vec2> ring;
  for (auto v = p.vertices_begin(); v != p.vertices_end(); ++v) ring.push_back({v->x(), v->y()});
  return ring;
}

double signed_ring_area(const std::vector<Vec2>& r) {
  double a = 0;
  for (std::size_t i = 0, n = r.size(); i < n; ++i) {
    const Vec2& p = r[i];
    const Vec2& q = r[(i + 1) % n];
    a += p[0] * q[1] - q[0] * p[1];
  }
  return a / 2;
}

// First moments (area-weighted) of a ring relative to `o`, for a well
// conditioned centroid far from the origin.
void ring_moments(const std::vector<Vec2>& r, Vec2 o, double& a, double& mx, double& my) {
  a = mx = my = 0;
  for (std::size_t i = 0, n = r.size(); i < n; ++i) {
    const double px = r[i][0] - o[0], py = r[i][1] - o[1];
    const double qx = r[(i + 1) % n][0] - o[0], qy = r[(i + 1) % n][1] - o[1];
    const double c = px * qy - qx * py;
    a += c;
    mx += (px + qx) * c;
    my += (py + qy) * c;
  }
  a /= 2;
  mx /= 6;
  my /= 6;
}

std::size_t vertex_count(const std::vector<Polygon2>& polys) {
  std::size_t n = 0;
  for (const auto& p : polys) {
    n += p.outer.size();
    for (const auto& h : p.holes) n += h.size();
  }
  return n;
}

double total_area(const std::vector<Polygon2>& polys) {
  double a = 0;
  for (const auto& p : polys) a += polygon_area(p);
  return a;
}

Vec2 total_centroid(const std::vector<Polygon2>& polys) {
  double a = 0, mx = 0, my = 0;
  const Vec2 o = polys.empty() || polys[0].outer.empty() ? Vec2{0, 0} : polys[0].outer[0];
  for (const auto& p : polys) {
    double ra, rx, ry;
    ring_moments(p.outer, o, ra, rx, ry);
    a += ra, mx += rx, my += ry;
    for (const auto& h : p.holes) {
      ring_moments(h, o, ra, rx, ry);
      a += ra, mx += rx, my += ry;
    }
  }
  if (a == 0) return o;
  return {o[0] + mx / a, o[1] + my / a};
}

}  // namespace

double polygon_area(const Polygon2& p) {
  double a = std::abs(signed_ring_area(p.outer));
  for (const auto& h : p.holes) a -= std::abs(signed_ring_area(h));
  return a;
}

Vec2 polygon_centroid(const Polygon2& p) { return total_centroid({p}); }

Vec2 ring_centroid(const std::vector<Vec2>& ring) {
  if (ring.empty()) return {0, 0};
  double a, mx, my;
  ring_moments(ring, ring[0], a, mx, my);
  if (a == 0) return ring[0];
  return {ring[0][0] + mx / a, ring[0][1] + my / a};
}

FootprintResult make_footprint(const std::vector<std::vector<Vec2>>& outers,
                               const std::vector<std::vector<Vec2>>& inners,
                               const FootprintOptions& opt) {
  FootprintResult result;
  Footprint fp;
  std::vector<EPolygon> outer_rings, inner_rings;
  for (const auto& r : outers) {
    fp.vertices_in += r.size();
    auto c = clean_ring(r, opt.duplicate_tolerance_m, fp.repairs.duplicate_nodes);
    if (c.size() >= 3) outer_rings.push_back(to_exact(c));
  }
  for (const auto& r : inners) {
    fp.vertices_in += r.size();
    auto c = clean_ring(r, opt.duplicate_tolerance_m, fp.repairs.duplicate_nodes);
    if (c.size() >= 3) inner_rings.push_back(to_exact(c));
  }
  if (outer_rings.empty()) {
    result.skip_reason = "degenerate";
    result.detail = "fewer than 3 distinct nodes";
    return result;
  }
  // The mesh needs outers counter-clockwise and holes clockwise; OSM leaves
  // winding open, so this is a normalisation, counted but not a defect.
  for (const auto& r : outer_rings)
    if (r.is_simple() && r.orientation() == CGAL::CLOCKWISE) fp.repairs.reoriented = true;
  for (const auto& r : inner_rings)
    if (r.is_simple() && r.orientation() == CGAL::COUNTERCLOCKWISE) fp.repairs.reoriented = true;

  EPolygonSet shape;
  std::size_t outer_components = 0;
  for (const auto& r : outer_rings) {
    EPolygonSet s = ring_set(r, fp.repairs);
    outer_components += s.number_of_polygons_with_holes();
    if (!shape.is_empty() && s.do_intersect(shape)) fp.repairs.rings_merged = true;
    shape.join(s);
  }
  EPolygonSet holes;
  for (const auto& r : inner_rings) holes.join(ring_set(r, fp.repairs));
  if (!holes.is_empty()) {
    // A hole that is not strictly inside the outline was mapped wrongly.
    std::vector<EPolygonWH> hp;
    holes.polygons_with_holes(std::back_inserter(hp));
    for (const auto& h : hp)
      for (auto v = h.outer_boundary().vertices_begin(); v != h.outer_boundary().vertices_end(); ++v)
        if (shape.oriented_side(*v) != CGAL::ON_POSITIVE_SIDE) fp.repairs.holes_fixed = true;
    shape.difference(holes);
  }
  std::vector<EPolygonWH> pieces;
  shape.polygons_with_holes(std::back_inserter(pieces));
  for (const auto& p : pieces) fp.polygons.push_back(to_double(p));
  (void)outer_components;

  const double area = total_area(fp.polygons);
  if (fp.polygons.empty() || !(area >= opt.min_area_m2)) {
    result.skip_reason = "zero_area";
    result.detail = "area " + std::to_string(area) + " m2 below " + std::to_string(opt.min_area_m2);
    return result;
  }
  const Vec2 centroid = total_centroid(fp.polygons);

  // Simplify within the tolerance; keep it only when area and centroid stay
  // within bounds (so the footprint still matches the map and SUMO).
  if (opt.simplify_tolerance_m > 0) {
    namespace PS = CGAL::Polyline_simplification_2;
    std::vector<Polygon2> simplified;
    bool ok = true;
    try {
      for (const auto& p : fp.polygons) {
        IPolygonWH in(to_inexact(p.outer));
        for (const auto& h : p.holes) in.add_hole(to_inexact(h));
        IPolygonWH outp = PS::simplify(in, PS::Squared_distance_cost(),
                                       PS::Stop_above_cost_threshold(opt.simplify_tolerance_m *
                                                                     opt.simplify_tolerance_m));
        Polygon2 q;
        q.outer = from_inexact(outp.outer_boundary());
        for (auto h = outp.holes_begin(); h != outp.holes_end(); ++h) q.holes.push_back(from_inexact(*h));
        if (q.outer.size() < 3 || !outp.outer_boundary().is_simple()) ok = false;
        simplified.push_back(std::move(q));
      }
    } catch (const std::exception&) {
      ok = false;
    }
    if (ok && vertex_count(simplified) < vertex_count(fp.polygons)) {
      const double a2 = total_area(simplified);
      const Vec2 c2 = total_centroid(simplified);
      const double shift = std::hypot(c2[0] - centroid[0], c2[1] - centroid[1]);
      if (std::abs(a2 - area) <= opt.max_area_change * area && shift <= opt.max_centroid_shift_m) {
        fp.polygons = std::move(simplified);
        fp.simplified = true;
      } else {
        fp.simplification_undone = true;
      }
    }
  }
  // Winding for the mesh: outer CCW, holes CW.
  for (auto& p : fp.polygons) {
    if (signed_ring_area(p.outer) < 0) std::reverse(p.outer.begin(), p.outer.end());
    for (auto& h : p.holes)
      if (signed_ring_area(h) > 0) std::reverse(h.begin(), h.end());
  }
  fp.area_m2 = total_area(fp.polygons);
  fp.centroid = total_centroid(fp.polygons);
  fp.vertices_out = vertex_count(fp.polygons);
  result.footprint = std::move(fp);
  return result;
}

namespace {

struct FaceInfo {
  int nesting = -1;
  bool inside() const { return nesting % 2 == 1; }
};
using Vb = CGAL::Triangulation_vertex_base_2<IK>;
using Fbi = CGAL::Triangulation_face_base_with_info_2<FaceInfo, IK>;
using Fb = CGAL::Constrained_triangulation_face_base_2<IK, Fbi>;
using Tds = CGAL::Triangulation_data_structure_2<Vb, Fb>;
using CDT = CGAL::Constrained_Delaunay_triangulation_2<IK, Tds, CGAL::Exact_predicates_tag>;

// Nesting level of every face: 0 outside, 1 inside the outline, 2 in a hole...
void mark_nesting(CDT& cdt) {
  std::deque<std::pair<CDT::Face_handle, int>> queue;
  queue.push_back({cdt.infinite_face(), 0});
  while (!queue.empty()) {
    auto [start, level] = queue.front();
    queue.pop_front();
    if (start->info().nesting != -1) continue;
    // Flood the region reachable without crossing constraints.
    std::deque<CDT::Face_handle> region{start};
    start->info().nesting = level;
    while (!region.empty()) {
      CDT::Face_handle f = region.front();
      region.pop_front();
      for (int i = 0; i < 3; ++i) {
        CDT::Face_handle n = f->neighbor(i);
        if (n->info().nesting != -1) continue;
        if (cdt.is_constrained(CDT::Edge(f, i))) {
          queue.push_back({n, level + 1});
        } else {
          n->info().nesting = level;
          region.push_back(n);
        }
      }
    }
  }
}

// A vertex where the outline touches itself (repaired bowties, holes touching
// the outline) joins separate wedges of the interior. Giving each wedge its own
// copy keeps the extruded prism 2-manifold: every edge bounds exactly two faces.
void split_pinch_vertices(TriangulatedPolygon& t, const std::vector<std::size_t>& edge_triangle) {
  std::vector<int> outgoing(t.vertices.size(), 0);
  for (const auto& e : t.boundary_edges) ++outgoing[e[0]];
  for (std::uint32_t v = 0; v < outgoing.size(); ++v) {
    if (outgoing[v] < 2) continue;
    // Triangles around v, joined across their shared interior edges (v, w).
    std::vector<std::size_t> around;
    for (std::size_t k = 0; k < t.triangles.size(); ++k)
      if (std::find(t.triangles[k].begin(), t.triangles[k].end(), v) != t.triangles[k].end()) around.push_back(k);
    auto is_boundary = [&](std::uint32_t a, std::uint32_t b) {
      for (const auto& e : t.boundary_edges)
        if ((e[0] == a && e[1] == b) || (e[0] == b && e[1] == a)) return true;
      return false;
    };
    std::vector<int> wedge(around.size(), -1);
    int wedges = 0;
    for (std::size_t s = 0; s < around.size(); ++s) {
      if (wedge[s] != -1) continue;
      std::vector<std::size_t> stack{s};
      wedge[s] = wedges;
      while (!stack.empty()) {
        const auto& ta = t.triangles[around[stack.back()]];
        stack.pop_back();
        for (std::size_t o = 0; o < around.size(); ++o) {
          if (wedge[o] != -1) continue;
          const auto& tb = t.triangles[around[o]];
          for (auto w : ta)
            if (w != v && std::find(tb.begin(), tb.end(), w) != tb.end() && !is_boundary(v, w)) {
              wedge[o] = wedges;
              stack.push_back(o);
              break;
            }
        }
      }
      ++wedges;
    }
    if (wedges < 2) continue;
    std::vector<std::uint32_t> copy(wedges, v);
    for (int w = 1; w < wedges; ++w) {
      copy[w] = static_cast<std::uint32_t>(t.vertices.size());
      t.vertices.push_back(t.vertices[v]);
    }
    std::map<std::size_t, int> wedge_of;
    for (std::size_t s = 0; s < around.size(); ++s) {
      wedge_of[around[s]] = wedge[s];
      for (auto& corner : t.triangles[around[s]])
        if (corner == v) corner = copy[wedge[s]];
    }
    for (std::size_t k = 0; k < t.boundary_edges.size(); ++k) {
      auto it = wedge_of.find(edge_triangle[k]);
      if (it == wedge_of.end()) continue;
      for (auto& end : t.boundary_edges[k])
        if (end == v) end = copy[it->second];
    }
  }
}

}  // namespace

TriangulatedPolygon triangulate(const Polygon2& polygon) {
  CDT cdt;
  auto insert_ring = [&cdt](const std::vector<Vec2>& ring) {
    std::vector<IK::Point_2> pts;
    for (const Vec2& v : ring) pts.emplace_back(v[0], v[1]);
    cdt.insert_constraint(pts.begin(), pts.end(), /*close=*/true);
  };
  insert_ring(polygon.outer);
  for (const auto& h : polygon.holes) insert_ring(h);
  mark_nesting(cdt);

  TriangulatedPolygon out;
  std::map<CDT::Vertex_handle, std::uint32_t> index;
  auto id = [&](CDT::Vertex_handle v) {
    auto [it, fresh] = index.emplace(v, static_cast<std::uint32_t>(out.vertices.size()));
    if (fresh) out.vertices.push_back({v->point().x(), v->point().y()});
    return it->second;
  };
  std::vector<std::size_t> edge_triangle;  // the triangle each boundary edge belongs to
  for (auto f = cdt.finite_faces_begin(); f != cdt.finite_faces_end(); ++f) {
    if (!f->info().inside()) continue;
    const std::uint32_t a = id(f->vertex(0)), b = id(f->vertex(1)), c = id(f->vertex(2));
    out.triangles.push_back({a, b, c});
    for (int i = 0; i < 3; ++i) {
      CDT::Face_handle n = f->neighbor(i);
      if (cdt.is_infinite(n) || !n->info().inside()) {
        out.boundary_edges.push_back({id(f->vertex(CDT::ccw(i))), id(f->vertex(CDT::cw(i)))});
        edge_triangle.push_back(out.triangles.size() - 1);
      }
    }
  }
  split_pinch_vertices(out, edge_triangle);
  return out;
}

bool footprint_contains(const Footprint& f, Vec2 p) {
  // The free function, not Polygon_2::bounded_side: the stored rings are
  // rounded to doubles and may touch themselves, which the member's
  // is_simple() precondition rejects (the sanitizer build checks it); the
  // crossing test itself is defined for any ring.
  const IK::Point_2 q(p[0], p[1]);
  auto side = [&](const std::vector<Vec2>& ring) {
    const IPolygon poly = to_inexact(ring);
    return CGAL::bounded_side_2(poly.vertices_begin(), poly.vertices_end(), q, IK());
  };
  for (const auto& poly : f.polygons) {
    if (side(poly.outer) != CGAL::ON_BOUNDED_SIDE) continue;
    bool in_hole = false;
    for (const auto& h : poly.holes)
      if (side(h) != CGAL::ON_UNBOUNDED_SIDE) in_hole = true;
    if (!in_hole) return true;
  }
  return false;
}

}  // namespace raysweep::meshkit
