// Native twin of the distance callback (gnppdsl/geometry/distance.py, WitnessCallback) for a
// pair of single-shape bodies: one coal query and the contact feature model of
// gnppdsl/geometry/features.py (feature_list, shape_feature), written as a casadi external
// function so that ipopt's evaluations of the graph-NLP never enter Python.
//
// Why: the Python callback costs ~40-50 us per query (coal itself ~6 us); on the Lab problems
// the distance queries were a quarter to a half of the solve time. The arithmetic below
// follows features.py line by line (same operations in the same order), so both give the same
// numbers; tests/geometry/test_geometry_native.py compares them on random poses.
//
// casadi external-function API (plain C, no casadi headers): gnpp_witness(x[24], pair[1]) ->
// o[24]; shapes and pairs are registered first through gnpp_add_shape / gnpp_add_pair (ctypes,
// the same loaded library: dlopen returns one handle per file).
#include <coal/collision_data.h>
#include <coal/distance.h>
#include <coal/shape/geometric_shapes.h>

#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <vector>

typedef long long casadi_int;

namespace {

const int N_OUT = 24;
const int CACHE = 4;   // ipopt evaluates g, its Jacobian and the Hessian at one point

typedef std::array<double, 3> V3;

inline V3 cross(const V3& a, const V3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
inline double dot(const V3& a, const V3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
inline V3 sub(const V3& a, const V3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
inline double norm(const V3& a) { return std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]); }

struct M3 {  // rows
  double r[3][3];
};
inline V3 mv(const M3& R, const V3& v) {
  return {R.r[0][0] * v[0] + R.r[0][1] * v[1] + R.r[0][2] * v[2],
          R.r[1][0] * v[0] + R.r[1][1] * v[1] + R.r[1][2] * v[2],
          R.r[2][0] * v[0] + R.r[2][1] * v[1] + R.r[2][2] * v[2]};
}
inline V3 mtv(const M3& R, const V3& v) {
  return {R.r[0][0] * v[0] + R.r[1][0] * v[1] + R.r[2][0] * v[2],
          R.r[0][1] * v[0] + R.r[1][1] * v[1] + R.r[2][1] * v[2],
          R.r[0][2] * v[0] + R.r[1][2] * v[1] + R.r[2][2] * v[2]};
}

V3 perp_unit(const V3& a) {
  int ax = 0;
  for (int i = 1; i < 3; ++i)
    if (std::fabs(a[i]) < std::fabs(a[ax])) ax = i;
  V3 e = {0.0, 0.0, 0.0};
  e[ax] = 1.0;
  V3 u = cross(a, e);
  double n = norm(u);
  return {u[0] / n, u[1] / n, u[2] / n};
}

enum Kind { SPHERE = 0, CYLINDER = 1, BOX = 2, OTHER = 3 };

struct Shape {
  int kind;
  double radius;
  V3 half;
  bool has_planes;
  std::vector<V3> N;              // merged outward unit normals (features._planes)
  std::vector<double> O;          // offsets
  std::vector<std::array<V3, 2>> dirs;   // two unit directions spanning each plane
  std::vector<char> side;         // horizontal normal (planar extrusions)
  double tol;
  std::shared_ptr<coal::ShapeBase> geom;
};

struct Placement {
  M3 R;
  V3 t;
  bool identity;
};

struct Pair {
  int a, b;
  Placement Ma, Mb;
  bool planar;
  double in[CACHE][24];
  double out[CACHE][N_OUT];
  int filled = 0, next = 0;
};

std::vector<Shape> g_shapes;
std::vector<Pair> g_pairs;
long long g_queries = 0;   // coal queries answered by gnpp_witness (not from the memo)
int g_fail_next = 0;       // test hook (gnpp_fail_next): plain queries to report as coal's failure

// coal's signed-distance request at the tolerances distance.py uses; `nesterov`: GJK with
// Nesterov acceleration (distance.robust_query's second request)
coal::DistanceRequest make_request(bool nesterov) {
  coal::DistanceRequest req;
  req.enable_signed_distance = true;
  req.gjk_tolerance = 1e-9;
  req.epa_tolerance = 1e-9;
  if (nesterov) req.gjk_variant = coal::GJKVariant::NesterovAcceleration;
  return req;
}

coal::DistanceRequest& request() {
  static coal::DistanceRequest req = make_request(false);
  return req;
}

coal::DistanceRequest& retry_request() {
  static coal::DistanceRequest req = make_request(true);
  return req;
}

// distance._good: coal's failure value (EPA giving up on shapes touching face to face) is
// -DBL_MAX with a NaN normal and NaN witness points
const double FAILED = 1e300;
bool good(double d, const coal::DistanceResult& res) {
  const coal::Vec3s& n = res.normal;
  const coal::Vec3s& w1 = res.nearest_points[0];
  const coal::Vec3s& w2 = res.nearest_points[1];
  return std::fabs(d) < FAILED && n.squaredNorm() >= 1e-24 && std::isfinite(w1.sum() + w2.sum());
}

// features.shape_feature: kind 0 none, 1 face (2 dirs), 2 edge (1 dir), 3 vertex, 4 sphere
struct Feature {
  int kind;
  V3 u[2];
  int n;
  double radius;
};

Feature shape_feature(const Shape& s, const V3& p, bool planar) {
  Feature f{0, {{0, 0, 0}, {0, 0, 0}}, 0, 0.0};
  if (s.kind == SPHERE || (planar && s.kind == CYLINDER)) {
    f.kind = 4;
    f.radius = s.radius;
    return f;
  }
  if (!s.has_planes) return f;
  int active[64];
  int na = 0;
  if (s.kind == BOX) {
    const double x = p[0], y = p[1], z = p[2], hx = s.half[0], hy = s.half[1], hz = s.half[2];
    const double gaps[6] = {x - hx, y - hy, z - hz, -x - hx, -y - hy, -z - hz};
    static const int all[6] = {0, 1, 2, 3, 4, 5}, side[4] = {0, 1, 3, 4};
    const int* idx = planar ? side : all;
    int m = planar ? 4 : 6;
    for (int k = 0; k < m; ++k)
      if (std::fabs(gaps[idx[k]]) < s.tol) active[na++] = idx[k];
  } else {
    for (size_t i = 0; i < s.N.size() && na < 64; ++i) {
      double g = std::fabs(s.N[i][0] * p[0] + s.N[i][1] * p[1] + s.N[i][2] * p[2] - s.O[i]);
      if (g < s.tol && (!planar || s.side[i])) active[na++] = (int)i;
    }
  }
  if (na == 0) return f;
  if (planar) {
    if (na == 1) {
      const V3& n = s.N[active[0]];
      f.kind = 2;
      f.n = 1;
      f.u[0] = {-n[1], n[0], 0.0};
      return f;
    }
    f.kind = 3;
    return f;
  }
  if (na == 1) {
    f.kind = 1;
    f.n = 2;
    f.u[0] = s.dirs[active[0]][0];
    f.u[1] = s.dirs[active[0]][1];
    return f;
  }
  V3 e = cross(s.N[active[0]], s.N[active[1]]);
  double ne = norm(e);
  if (ne < 1e-9) return f;
  e = {e[0] / ne, e[1] / ne, e[2] / ne};
  for (int k = 2; k < na; ++k)
    if (!(std::fabs(dot(s.N[active[k]], e)) < 1e-7)) {
      f.kind = 3;
      return f;
    }
  f.kind = 2;
  f.n = 1;
  f.u[0] = e;
  return f;
}

// features.feature_list
void feature_list(const Pair& P, const M3& RA, const V3& pA, const M3& RB, const V3& pB, double d,
                  const V3& n, const V3& wa, const V3& wb, double* out) {
  const Shape& sa = g_shapes[P.a];
  const Shape& sb = g_shapes[P.b];
  const bool planar = P.planar;
  V3 la = mtv(RA, sub(wa, pA));
  V3 lb = mtv(RB, sub(wb, pB));
  static const double init[N_OUT] = {0, 0, 0, 1, 1, 0, 0, 0, 0, 0, 0, 1,
                                     0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0};
  std::memcpy(out, init, sizeof(init));
  out[21] = n[0];
  out[22] = n[1];
  out[23] = n[2];
  Feature fa = shape_feature(sa, P.Ma.identity ? la : mtv(P.Ma.R, sub(la, P.Ma.t)), planar);
  Feature fb = shape_feature(sb, P.Mb.identity ? lb : mtv(P.Mb.R, sub(lb, P.Mb.t)), planar);
  if (planar) {
    la[2] = 0.0;
    lb[2] = 0.0;
  }
  for (int i = 0; i < 3; ++i) {
    out[5 + i] = la[i];
    out[8 + i] = lb[i];
  }
  if (fa.kind == 0 || fb.kind == 0) return;
  double ra = 0.0, rb = 0.0;
  V3 du[4];
  int downer[4];
  int nd = 0;
  const Feature* fs[2] = {&fa, &fb};
  const Placement* pls[2] = {&P.Ma, &P.Mb};
  for (int owner = 0; owner < 2; ++owner) {
    const Feature& f = *fs[owner];
    const Placement& pl = *pls[owner];
    if (f.kind == 4) {
      V3 c = {pl.t[0], pl.t[1], planar ? 0.0 : pl.t[2]};
      if (owner == 0) {
        ra = f.radius;
        la = c;
      } else {
        rb = f.radius;
        lb = c;
      }
    } else {
      for (int k = 0; k < f.n; ++k) {
        du[nd] = mv(pl.R, f.u[k]);
        downer[nd++] = owner;
      }
    }
  }
  if (nd > 2) {  // face-face / face-edge (parallel): keep a face
    int face_owner = fa.kind == 1 ? 0 : 1;
    int m = 0;
    for (int k = 0; k < nd && m < 2; ++k)
      if (downer[k] == face_owner) {
        du[m] = du[k];
        downer[m++] = downer[k];
      }
    nd = m;
  }
  const M3* R[2] = {&RA, &RB};
  V3 v = sub(sub(mv(RB, lb), mv(RA, la)), sub(pA, pB));
  int mode = -1;
  double s = 1.0, val = 0.0;
  if (nd == 2) {
    V3 c = cross(mv(*R[downer[0]], du[0]), mv(*R[downer[1]], du[1]));
    double nc = norm(c);
    if (nc < 1e-6) {
      nd = 1;
    } else {
      s = dot(c, n) >= 0 ? 1.0 : -1.0;
      val = s * dot(c, v) / nc - ra - rb;
      mode = 0;
    }
  }
  if (nd == 1) {
    V3 e = mv(*R[downer[0]], du[0]);
    double ev = dot(e, v);
    s = d + ra + rb >= 0 ? 1.0 : -1.0;
    V3 w = {v[0] - ev * e[0], v[1] - ev * e[1], v[2] - ev * e[2]};
    val = s * norm(w) - ra - rb;
    mode = 1;
  } else if (nd == 0) {
    s = d + ra + rb >= 0 ? 1.0 : -1.0;
    val = s * norm(v) - ra - rb;
    mode = 2;
  }
  if (mode < 0 || std::fabs(val - d) > 1e-7 * std::fmax(1.0, std::fabs(d))) return;
  out[0] = out[1] = out[2] = out[3] = 0.0;
  out[mode] = 1.0;
  out[4] = s;
  for (int i = 0; i < 3; ++i) {
    out[5 + i] = la[i];
    out[8 + i] = lb[i];
  }
  if (nd > 0) {
    for (int i = 0; i < 3; ++i) out[11 + i] = du[0][i];
    out[17] = downer[0];
    out[18] = downer[0];
    if (nd == 2) {
      for (int i = 0; i < 3; ++i) out[14 + i] = du[1][i];
      out[18] = downer[1];
    } else {
      V3 q = perp_unit(du[0]);
      for (int i = 0; i < 3; ++i) out[14 + i] = q[i];
    }
  }
  out[19] = ra;
  out[20] = rb;
}

void place(coal::Transform3s& T, const M3& R, const V3& p, const Placement& M) {
  coal::Matrix3s Rm;
  coal::Vec3s t;
  if (M.identity) {
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) Rm(i, j) = R.r[i][j];
      t(i) = p[i];
    }
  } else {
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j)
        Rm(i, j) = R.r[i][0] * M.R.r[0][j] + R.r[i][1] * M.R.r[1][j] + R.r[i][2] * M.R.r[2][j];
      t(i) = R.r[i][0] * M.t[0] + R.r[i][1] * M.t[1] + R.r[i][2] * M.t[2] + p[i];
    }
  }
  T.setRotation(Rm);
  T.setTranslation(t);
}

// WitnessCallback._single_list, with _model_general's fallback for a degenerate query
void witness_model(const Pair& P, const double* x, double* out) {
  M3 RA, RB;   // x holds vec(R) column-major: R(i, j) = x[i + 3 j]
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      RA.r[i][j] = x[i + 3 * j];
      RB.r[i][j] = x[12 + i + 3 * j];
    }
  V3 pA = {x[9], x[10], x[11]}, pB = {x[21], x[22], x[23]};
  coal::Transform3s Ta, Tb;
  place(Ta, RA, pA, P.Ma);
  place(Tb, RB, pB, P.Mb);
  const coal::ShapeBase* ga = g_shapes[P.a].geom.get();
  const coal::ShapeBase* gb = g_shapes[P.b].geom.get();
  coal::DistanceResult res;
  double d = coal::distance(ga, Ta, gb, Tb, request(), res);
  if (g_fail_next > 0) {   // test hook: coal's failure as measured (see good)
    --g_fail_next;
    const double nan = std::numeric_limits<double>::quiet_NaN();
    d = -std::numeric_limits<double>::max();
    res.normal.setConstant(nan);
    res.nearest_points[0].setConstant(nan);
    res.nearest_points[1].setConstant(nan);
  }
  bool swapped = false;
  if (!good(d, res)) {   // distance.robust_query: the shapes swapped, then Nesterov's GJK
    coal::DistanceResult r2;
    double d2 = coal::distance(gb, Tb, ga, Ta, request(), r2);
    if (good(d2, r2)) {
      d = d2, res = r2, swapped = true;
    } else {
      coal::DistanceResult r3;
      double d3 = coal::distance(ga, Ta, gb, Tb, retry_request(), r3);
      if (good(d3, r3)) d = d3, res = r3;
    }
  }
  V3 n = {res.normal(0), res.normal(1), res.normal(2)};
  if (swapped) n = {-n[0], -n[1], -n[2]};
  double nn = std::sqrt(dot(n, n));
  V3 wa, wb;
  if (!good(d, res) || !(nn >= 1e-12)) {   // touching exactly: the centre direction
    V3 c = sub(pB, pA);
    double nc = norm(c);
    n = nc > 1e-12 ? V3{c[0] / nc, c[1] / nc, c[2] / nc} : V3{0.0, 0.0, 1.0};
    wa = wb = V3{(pA[0] + pB[0]) / 2, (pA[1] + pB[1]) / 2, (pA[2] + pB[2]) / 2};
    d = 0.0;
  } else {
    n = {n[0] / nn, n[1] / nn, n[2] / nn};
    const coal::Vec3s& w1 = res.nearest_points[swapped ? 1 : 0];
    const coal::Vec3s& w2 = res.nearest_points[swapped ? 0 : 1];
    wa = {w1(0), w1(1), w1(2)};
    wb = {w2(0), w2(1), w2(2)};
  }
  feature_list(P, RA, pA, RB, pB, d, n, wa, wb, out);
}

Placement placement_of(const double* M, int identity) {
  Placement pl;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) pl.R.r[i][j] = M[3 * i + j];
    pl.t[i] = M[9 + i];
  }
  pl.identity = identity != 0;
  return pl;
}

const casadi_int SP_IN0[] = {24, 1, 0, 24, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11,
                             12, 13, 14, 15, 16, 17, 18, 19, 20, 21, 22, 23};
const casadi_int SP_IN1[] = {1, 1, 0, 1, 0};

}  // namespace

extern "C" {

int gnpp_native_abi(void) { return 1; }

// A shape: kind (0 sphere, 1 cylinder, 2 box, 3 convex hull of `points`), its size, and the
// merged face planes of features._planes (normals, offsets, spanning directions, side flags).
// Returns its id, or -1 when coal rejects it.
int gnpp_add_shape(int kind, double radius, double length, const double* half, const double* points,
                   int n_points, int n_planes, const double* normals, const double* offsets,
                   const double* dirs, const int* side, double tol) {
  try {
    Shape s;
    s.kind = kind;
    s.radius = radius;
    s.half = {half[0], half[1], half[2]};
    s.tol = tol;
    s.has_planes = n_planes > 0;
    for (int i = 0; i < n_planes; ++i) {
      s.N.push_back({normals[3 * i], normals[3 * i + 1], normals[3 * i + 2]});
      s.O.push_back(offsets[i]);
      s.dirs.push_back({V3{dirs[6 * i], dirs[6 * i + 1], dirs[6 * i + 2]},
                        V3{dirs[6 * i + 3], dirs[6 * i + 4], dirs[6 * i + 5]}});
      s.side.push_back(side[i] != 0);
    }
    if (kind == SPHERE) {
      s.geom = std::make_shared<coal::Sphere>(radius);
    } else if (kind == CYLINDER) {
      s.geom = std::make_shared<coal::Cylinder>(radius, length);
    } else if (kind == BOX) {
      s.geom = std::make_shared<coal::Box>(2 * half[0], 2 * half[1], 2 * half[2]);
    } else {
      auto pts = std::make_shared<std::vector<coal::Vec3s>>();
      for (int i = 0; i < n_points; ++i)
        pts->push_back(coal::Vec3s(points[3 * i], points[3 * i + 1], points[3 * i + 2]));
      coal::ConvexBase* hull = coal::ConvexBase::convexHull(pts, (unsigned)n_points, false, NULL);
      if (hull == NULL) return -1;
      s.geom.reset(hull);
    }
    g_shapes.push_back(std::move(s));
    return (int)g_shapes.size() - 1;
  } catch (...) {
    return -1;
  }
}

// A body pair: two shape ids with their placements in the body frames (rotation rows, then the
// translation: 12 numbers) and identity flags. Returns its id (the second input of gnpp_witness).
int gnpp_add_pair(int a, const double* Ma, int ida, int b, const double* Mb, int idb, int planar) {
  if (a < 0 || b < 0 || a >= (int)g_shapes.size() || b >= (int)g_shapes.size()) return -1;
  Pair p;
  p.a = a;
  p.b = b;
  p.Ma = placement_of(Ma, ida);
  p.Mb = placement_of(Mb, idb);
  p.planar = planar != 0;
  g_pairs.push_back(p);
  return (int)g_pairs.size() - 1;
}

// Forget remembered answers (GeometryContext.forget_evaluations).
void gnpp_forget(void) {
  for (Pair& p : g_pairs) p.filled = p.next = 0;
}

// Test hook: the next k plain coal queries report coal's failure value (-DBL_MAX, NaN normal
// and witness points), so that tests reach the retries, which coal answers for real.
void gnpp_fail_next(int k) { g_fail_next = k; }

// Number of queries gnpp_witness computed (memo hits not counted): tests of the memo.
long long gnpp_queries(void) { return g_queries; }

// One query without the memo (tests).
int gnpp_model(int pair, const double* x, double* out) {
  if (pair < 0 || pair >= (int)g_pairs.size()) return 1;
  try {
    witness_model(g_pairs[pair], x, out);
  } catch (...) {
    return 1;
  }
  return 0;
}

// ---- casadi external function gnpp_witness: (x[24], pair[1]) -> o[24] ----
int gnpp_witness(const double** arg, double** res, casadi_int* iw, double* w, int mem) {
  (void)iw;
  (void)w;
  (void)mem;
  if (!res[0]) return 0;
  int id = arg[1] ? (int)arg[1][0] : -1;
  if (id < 0 || id >= (int)g_pairs.size() || !arg[0]) return 1;
  Pair& P = g_pairs[id];
  const double* x = arg[0];
  for (int k = 0; k < P.filled; ++k)
    if (std::memcmp(P.in[k], x, sizeof(P.in[k])) == 0) {
      std::memcpy(res[0], P.out[k], sizeof(P.out[k]));
      return 0;
    }
  double out[N_OUT];
  try {
    witness_model(P, x, out);
  } catch (...) {
    return 1;
  }
  ++g_queries;
  int slot = P.next;
  std::memcpy(P.in[slot], x, sizeof(P.in[slot]));
  std::memcpy(P.out[slot], out, sizeof(out));
  P.next = (slot + 1) % CACHE;
  if (P.filled < CACHE) P.filled++;
  std::memcpy(res[0], out, sizeof(out));
  return 0;
}

casadi_int gnpp_witness_n_in(void) { return 2; }
casadi_int gnpp_witness_n_out(void) { return 1; }
const casadi_int* gnpp_witness_sparsity_in(casadi_int i) { return i == 0 ? SP_IN0 : SP_IN1; }
const casadi_int* gnpp_witness_sparsity_out(casadi_int i) { return SP_IN0; }
int gnpp_witness_work(casadi_int* sz_arg, casadi_int* sz_res, casadi_int* sz_iw, casadi_int* sz_w) {
  if (sz_arg) *sz_arg = 2;
  if (sz_res) *sz_res = 1;
  if (sz_iw) *sz_iw = 0;
  if (sz_w) *sz_w = 0;
  return 0;
}

}  // extern "C"
