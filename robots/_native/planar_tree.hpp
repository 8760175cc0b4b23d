// The joint-space dynamics and the frame kinematics of a robot moving in a plane, from its
// Pinocchio model (pinlegsim.cpp uses them for every model that is planar; see PlanarTree).
//
// Units: SI throughout; angles in rad.

#pragma once

#include <pinocchio/multibody.hpp>

#include <Eigen/Core>

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <vector>

namespace legsim_planar {

// The bridge's robots move in the x-z plane: their revolute joints turn about y, their
// prismatic joints slide along x or z, their joint placements map the y axis onto itself (a turn
// about y, or a half turn that reverses it: a joint turning the other way), and gravity lies in
// the plane. Their joint-space inertia M(q) and bias forces h(q, v) are then those of planar
// bodies, each a mass, a centre of mass in the plane and an inertia about y (Pinocchio's 6-D
// algorithms carry the other three axes through every pass to find them zero). PlanarTree holds
// a planar model's joints in Pinocchio's order and computes M and h from them in a fraction of
// crba's and RNEA's time; a model that is not planar keeps Pinocchio's algorithms. M and h are
// Pinocchio's to rounding (tests/robots/test_compiled_robots.py).
struct PlanarTree {
  enum Kind { REVOLUTE = 0, SLIDE_X = 1, SLIDE_Z = 2 };
  // A map of the plane: the x-z block of a rotation that maps y onto sign * y (the block's
  // determinant is that sign).
  struct Axes {
    double xx = 1.0, xz = 0.0, zx = 0.0, zz = 1.0, sign = 1.0;
    Axes then(const Axes& b) const {
      return Axes{xx * b.xx + xz * b.zx, xx * b.xz + xz * b.zz, zx * b.xx + zz * b.zx, zx * b.xz + zz * b.zz,
                  sign * b.sign};
    }
    double x(double px, double pz) const { return xx * px + xz * pz; }
    double z(double px, double pz) const { return zx * px + zz * pz; }
  };
  struct Joint {
    long parent;                   // its parent joint (0: the world)
    int kind;                      // Kind
    Axes placement;                // its placement's axes in the parent's
    double px, pz;                 // its placement's origin in the parent's axes (m)
    long v;                        // its velocity index
    double mass, cx, cz, inertia;  // its body: kg, centre of mass in the joint's axes (m), kg m^2 about y there
  };
  // Each joint frame at (q, v): its axes, its origin (m) and that origin's velocity (m/s), its
  // angular velocity about the world's y (rad/s) and its origin's acceleration at zero joint
  // acceleration (m/s^2); a slide's axis in the world; its body's centre of mass (m) and that
  // centre's acceleration at zero joint acceleration (m/s^2).
  struct Frame {
    Axes axes;
    double ox = 0.0, oz = 0.0, vx = 0.0, vz = 0.0, w = 0.0, ax = 0.0, az = 0.0, ex = 0.0, ez = 0.0;
    double cx = 0.0, cz = 0.0, acx = 0.0, acz = 0.0;
    // The velocity (x, z) of the body's material point at (x, z) in the world: the origin's plus
    // w x r, which for w along y is w (r_z, -r_x).
    std::array<double, 2> velocity_at(double x, double z) const { return {vx + w * (z - oz), vz - w * (x - ox)}; }
  };
  // A model frame: its joint and its origin in the joint's axes (m).
  struct Point {
    long joint;
    double px, pz;
  };
  bool valid = false;
  double gx = 0.0, gz = 0.0;               // gravity (m/s^2)
  std::vector<Joint> joints;               // [0] the world
  std::vector<std::vector<long>> support;  // each joint's ancestors and itself, root first
  std::vector<Frame> frames;
  std::vector<Point> points;               // the model's frames, by frame id
  std::vector<std::array<double, 3>> columns;  // scratch: one body's Jacobian columns (planar_column)
  // The (q, v) the frames were last computed at (frames_at), n entries each once known.
  std::vector<double> frames_q, frames_v;
};

// The planar tree of `model`, or one with valid = false where the model is not planar.
template <typename PinocchioModel>
PlanarTree planar_tree(const PinocchioModel& model) {
  PlanarTree tree;
  constexpr double tol = 1e-12;
  const Eigen::Vector3d gravity = model.gravity.linear();
  // Rotor inertias (armature), which Pinocchio's crba adds to M's diagonal, are not bodies of the
  // plane: a model with them keeps Pinocchio's algorithms.
  if (gravity(1) != 0.0 || !model.armature.isZero(0.0)) return tree;
  tree.gx = gravity(0);
  tree.gz = gravity(2);
  const auto count = static_cast<size_t>(model.njoints);
  tree.joints.resize(count);
  tree.support.resize(count);
  tree.frames.resize(count);
  tree.columns.resize(count);
  for (pinocchio::JointIndex j = 1; j < count; ++j) {
    const std::string name = model.joints[j].shortname();
    const int kind = name == "JointModelRY"   ? PlanarTree::REVOLUTE
                     : name == "JointModelPX" ? PlanarTree::SLIDE_X
                     : name == "JointModelPZ" ? PlanarTree::SLIDE_Z
                                              : -1;
    if (kind < 0 || model.joints[j].nv() != 1) return tree;
    const Eigen::Matrix3d& R = model.jointPlacements[j].rotation();
    const bool keeps_y = std::abs(std::abs(R(1, 1)) - 1.0) <= tol && std::abs(R(0, 1)) <= tol &&
                         std::abs(R(2, 1)) <= tol && std::abs(R(1, 0)) <= tol && std::abs(R(1, 2)) <= tol;
    if (!keeps_y) return tree;
    const PlanarTree::Axes axes{R(0, 0), R(0, 2), R(2, 0), R(2, 2), R(1, 1) > 0.0 ? 1.0 : -1.0};
    const Eigen::Vector3d& p = model.jointPlacements[j].translation();
    const pinocchio::Inertia& body = model.inertias[j];
    tree.joints[j] = PlanarTree::Joint{static_cast<long>(model.parents[j]), kind, axes, p(0), p(2),
                                       static_cast<long>(model.joints[j].idx_v()), body.mass(), body.lever()(0),
                                       body.lever()(2), body.inertia().matrix()(1, 1)};
    for (pinocchio::JointIndex a : model.supports[j])
      if (a > 0) tree.support[j].push_back(static_cast<long>(a));
  }
  for (const auto& frame : model.frames) {
    const Eigen::Vector3d& p = frame.placement.translation();
    tree.points.push_back(PlanarTree::Point{static_cast<long>(frame.parentJoint), p(0), p(2)});
  }
  tree.valid = true;
  return tree;
}

// Each joint frame of `tree` at (q, v), root first (PlanarTree::Frame). A revolute joint turns its
// frame about its origin (about the world's y or, in reversed axes, against it); a slide moves
// the origin along its axis, the Coriolis term 2 w x (qd e) joining the parent's centripetal
// one. For w along y, w x r = w (r_z, -r_x) in the plane.
inline void planar_frames(PlanarTree& tree, const double* q, const double* v) {
  for (size_t j = 1; j < tree.joints.size(); ++j) {
    const PlanarTree::Joint& J = tree.joints[j];
    const PlanarTree::Frame& P = tree.frames[static_cast<size_t>(J.parent)];
    PlanarTree::Frame& F = tree.frames[j];
    const double rx = P.axes.x(J.px, J.pz), rz = P.axes.z(J.px, J.pz);
    const double w2 = P.w * P.w;
    F.ox = P.ox + rx;
    F.oz = P.oz + rz;
    F.vx = P.vx + P.w * rz;
    F.vz = P.vz - P.w * rx;
    F.ax = P.ax - w2 * rx;
    F.az = P.az - w2 * rz;
    const PlanarTree::Axes before = P.axes.then(J.placement);
    const double qj = q[J.v], vj = v[J.v];
    if (J.kind == PlanarTree::REVOLUTE) {
      const double c = std::cos(qj), s = std::sin(qj);
      F.axes = before.then(PlanarTree::Axes{c, s, -s, c, 1.0});
      F.w = P.w + before.sign * vj;
    } else {
      const bool along_x = J.kind == PlanarTree::SLIDE_X;
      F.ex = along_x ? before.xx : before.xz;
      F.ez = along_x ? before.zx : before.zz;
      F.ox += qj * F.ex;
      F.oz += qj * F.ez;
      F.vx += P.w * qj * F.ez + vj * F.ex;
      F.vz += -P.w * qj * F.ex + vj * F.ez;
      F.ax += -w2 * qj * F.ex + 2.0 * P.w * vj * F.ez;
      F.az += -w2 * qj * F.ez - 2.0 * P.w * vj * F.ex;
      F.axes = before;
      F.w = P.w;
    }
    const double dx = F.axes.x(J.cx, J.cz), dz = F.axes.z(J.cx, J.cz);
    F.cx = F.ox + dx;
    F.cz = F.oz + dz;
    F.acx = F.ax - F.w * F.w * dx;
    F.acz = F.az - F.w * F.w * dz;
  }
}

// The frames at (q, v) of n entries each, computed unless they already are. A field evaluation
// reads them several times at one state (a leg's hip Jacobian each, then M and h), and the guards
// after a step at the state its last stage evaluated. With positions_only, the caller reads only
// the frames' axes and positions, which frames computed at q with any v serve (v is then only
// used when they are computed anew).
inline void frames_at(PlanarTree& tree, const double* q, const double* v, long n, bool positions_only) {
  const auto size = static_cast<size_t>(n);
  const bool known = tree.frames_q.size() == size && std::equal(q, q + n, tree.frames_q.begin()) &&
                     (positions_only || std::equal(v, v + n, tree.frames_v.begin()));
  if (known) return;
  planar_frames(tree, q, v);
  tree.frames_q.assign(q, q + n);
  tree.frames_v.assign(v, v + n);
}

// Column `joint` of the Jacobian of a point (x, z) of a body below that joint: the point's
// velocity (x, z) and the body's turn about y per unit of the joint's rate.
inline std::array<double, 3> planar_column(const PlanarTree& tree, long joint, double x, double z) {
  const PlanarTree::Frame& A = tree.frames[static_cast<size_t>(joint)];
  if (tree.joints[static_cast<size_t>(joint)].kind != PlanarTree::REVOLUTE) return {A.ex, A.ez, 0.0};
  const double sign = A.axes.sign;
  return {sign * (z - A.oz), -sign * (x - A.ox), sign};
}

// Each nonzero column of the Jacobian of a body's point (x, z), the body below joint `joint`:
// column(velocity index, {x, z, turn}) for each of its supporting joints (planar_column).
template <typename Column>
inline void planar_columns(const PlanarTree& tree, long joint, double x, double z, Column column) {
  for (long k : tree.support[static_cast<size_t>(joint)])
    column(tree.joints[static_cast<size_t>(k)].v, planar_column(tree, k, x, z));
}

// The world position (x, z) of a point at (px, pz) in joint `joint`'s axes plus `offset` (x, z in
// the world's axes: a round frame's contact point), after planar_frames.
inline std::array<double, 2> planar_point(const PlanarTree& tree, long frame, const Eigen::Vector3d& offset) {
  const PlanarTree::Point& P = tree.points[static_cast<size_t>(frame)];
  const PlanarTree::Frame& F = tree.frames[static_cast<size_t>(P.joint)];
  return {F.ox + F.axes.x(P.px, P.pz) + offset(0), F.oz + F.axes.z(P.px, P.pz) + offset(2)};
}

// M(q) (n, n, both triangles) and h(q, v) (n) of a planar tree: the sums over its bodies of
// m Jc^T Jc + I Jw^T Jw and of m Jc^T (a_c - g), Jc the Jacobian of the body's centre of mass
// and Jw of its turn, a_c that centre's acceleration at zero joint acceleration.
inline void planar_dynamics(PlanarTree& tree, const double* q, const double* v, long n, Eigen::MatrixXd& M,
                            Eigen::VectorXd& h) {
  frames_at(tree, q, v, n, false);
  M.setZero(n, n);
  h.setZero(n);
  std::vector<std::array<double, 3>>& columns = tree.columns;
  for (size_t b = 1; b < tree.joints.size(); ++b) {
    const PlanarTree::Joint& body = tree.joints[b];
    if (body.mass == 0.0 && body.inertia == 0.0) continue;
    const PlanarTree::Frame& B = tree.frames[b];
    const std::vector<long>& support = tree.support[b];
    for (size_t i = 0; i < support.size(); ++i) columns[i] = planar_column(tree, support[i], B.cx, B.cz);
    const double fx = body.mass * (B.acx - tree.gx), fz = body.mass * (B.acz - tree.gz);
    for (size_t i = 0; i < support.size(); ++i) {
      const std::array<double, 3>& ci = columns[i];
      const long vi = tree.joints[static_cast<size_t>(support[i])].v;
      h(vi) += ci[0] * fx + ci[1] * fz;
      for (size_t k = 0; k < support.size(); ++k) {
        const std::array<double, 3>& ck = columns[k];
        M(vi, tree.joints[static_cast<size_t>(support[k])].v) +=
            body.mass * (ci[0] * ck[0] + ci[1] * ck[1]) + body.inertia * ci[2] * ck[2];
      }
    }
  }
}

}  // namespace legsim_planar
