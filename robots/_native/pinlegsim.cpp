// Pinocchio's rigid-body algorithms behind a plain C ABI, for the robots' model functions
// (legsim.robots.bridge: numba-compiled functions that the Python loop and the compiled kernel
// both call). Every function takes a model handle and raw float64 pointers; numba calls them by
// symbol name (numba.types.ExternalFunction), so a compiled function that calls them caches on
// disk like any other.
//
// The algorithms: the forward dynamics a0 = M^-1 (tau - h(q, v)) under applied forces (M and the
// bias forces h from the planar bodies of a robot moving in the x-z plane, planar_tree.hpp, else by
// crba and RNEA; a Cholesky factor of M); the KKT contact dynamics through the Schur
// complement (lambda = (J M^-1 J^T)^-1 (-(J a0 + dJ/dt v)), a = a0 + M^-1 J^T lambda, M^-1 J^T
// from the same factor); the generalised Newton impact; M and M^-1; frame positions, velocities and Jacobians
// in the world's axes. Each robot counts the algorithms it ran (lsn_counts), and the model
// functions add their own counts (lsn_tally), so a robot's evaluations are known whichever path
// ran them.
//
// Pinocchio is used header-only (no PINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION): the library
// needs no libpinocchio at run time and no ABI match with the installed Python bindings.
//
// Units: SI throughout. Arrays: q, v, tau, a of size nv; a Jacobian block is row-major.

#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/center-of-mass.hpp>
#include <pinocchio/algorithm/centroidal.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/jacobian.hpp>
#include <pinocchio/algorithm/kinematics.hpp>
#include <pinocchio/algorithm/rnea.hpp>
#include <pinocchio/multibody.hpp>

#include "planar_tree.hpp"
#include "small_cholesky.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <Eigen/SVD>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstring>
#include <initializer_list>
#include <cmath>
#include <limits>
#include <memory>
#include <mutex>
#include <vector>

namespace {

using legsim_planar::PlanarTree;
using legsim_planar::frames_at;
using legsim_planar::planar_columns;
using legsim_planar::planar_dynamics;
using legsim_planar::planar_point;
using legsim_planar::planar_tree;

// The joints the bridge admits (nq == nv: bounded revolute and prismatic joints along the
// axes). A collection of these six alone, rather than Pinocchio's default of 25 kinds, keeps
// every algorithm's joint dispatch small: the library compiles in a fraction of the time and
// runs the same arithmetic. It holds no composite joint: a description's composite (the planar
// root) is built as its parts (read_joint), and a composite kind in the variant would cost a
// fifth of the library's compile time for a joint never made.
template <typename S, int O>
struct PlanarJointsTpl {
  typedef S Scalar;
  static constexpr int Options = O;
  typedef pinocchio::JointModelRevoluteTpl<S, O, 0> JointModelRX;
  typedef pinocchio::JointModelRevoluteTpl<S, O, 1> JointModelRY;
  typedef pinocchio::JointModelRevoluteTpl<S, O, 2> JointModelRZ;
  typedef pinocchio::JointModelPrismaticTpl<S, O, 0> JointModelPX;
  typedef pinocchio::JointModelPrismaticTpl<S, O, 1> JointModelPY;
  typedef pinocchio::JointModelPrismaticTpl<S, O, 2> JointModelPZ;
  // Pinocchio's model and data look for mimic joints by type: the variant must name them.
  typedef pinocchio::JointModelMimicTpl<S, O, PlanarJointsTpl> JointModelMimic;
  typedef boost::variant<JointModelRX, JointModelRY, JointModelRZ, JointModelPX, JointModelPY, JointModelPZ,
                         boost::recursive_wrapper<JointModelMimic>>
      JointModelVariant;
  typedef pinocchio::JointDataRevoluteTpl<S, O, 0> JointDataRX;
  typedef pinocchio::JointDataRevoluteTpl<S, O, 1> JointDataRY;
  typedef pinocchio::JointDataRevoluteTpl<S, O, 2> JointDataRZ;
  typedef pinocchio::JointDataPrismaticTpl<S, O, 0> JointDataPX;
  typedef pinocchio::JointDataPrismaticTpl<S, O, 1> JointDataPY;
  typedef pinocchio::JointDataPrismaticTpl<S, O, 2> JointDataPZ;
  typedef pinocchio::JointDataMimicTpl<S, O, PlanarJointsTpl> JointDataMimic;
  typedef boost::variant<JointDataRX, JointDataRY, JointDataRZ, JointDataPX, JointDataPY, JointDataPZ,
                         boost::recursive_wrapper<JointDataMimic>>
      JointDataVariant;
};

using Model = pinocchio::ModelTpl<double, 0, PlanarJointsTpl>;
using Data = pinocchio::DataTpl<double, 0, PlanarJointsTpl>;
using SE3 = pinocchio::SE3;
using Vec = Eigen::VectorXd;
using Mat = Eigen::MatrixXd;
using ConstMap = Eigen::Map<const Vec>;
using OutMap = Eigen::Map<Vec>;

constexpr int kVersion = 13;

// Joint type codes of the model description (see lsn_create).
enum JointCode { RX = 0, RY = 1, RZ = 2, PX = 3, PY = 4, PZ = 5, COMPOSITE = 6 };
using Joints = PlanarJointsTpl<double, 0>;
using JointModel = pinocchio::JointModelTpl<double, 0, PlanarJointsTpl>;

// A constraint row block: a joint stop (one row selecting a signed dof), a point contact
// (rows x and z of the frame's world-aligned Jacobian, or z only) or a slipping point (row z;
// its force acts along W = J_z - s mu J_x, the friction force -s mu lambda_n joining the
// normal force); the normal row is the last.
enum RigidKind { STOP = 0, POINT = 1, SLIPPING_POINT = 2 };

struct Rigid {
  int kind;     // RigidKind
  int id;       // stop: velocity index; point: frame id
  double sign;  // stop: the side (+-1); slipping point: s mu; stuck point: mu (< 0: none)
  int rows;
};

// Evaluation counters of a robot, by slot (legsim.robots.bridge.native.COUNTERS names them):
// the first ones are counted here, the others by the model functions through lsn_tally.
enum Counter { ABA = 0, KKT = 1, JACOBIANS = 2, KINEMATICS = 3, IMPACTS = 4, CACHE_HITS = 9, COUNTERS = 16 };

// The last solve of one algorithm, by its inputs: a mode's guards at a step's end and its field
// at the next step's first stage share one solve (same state, same input), as do the
// controller's and the field's gravity terms. Inputs are compared bit for bit, in place: a solve
// that misses (most do) copies its inputs once, into storage sized at the first solve, so that
// a call allocates nothing.
struct SolveCache {
  std::vector<double> key, pending, first, second;
  // Whether the inputs (their parts end to end) are the last solve's; on a miss, pending keeps
  // them for store() (the outputs may overwrite an input).
  bool hit(std::initializer_list<std::pair<const double*, long>> parts) {
    size_t size = 0;
    for (const auto& part : parts) size += static_cast<size_t>(part.second);
    bool same = !key.empty() && size == key.size();
    size_t at = 0;
    for (const auto& part : parts) {
      if (!same) break;
      if (part.second > 0) same = std::memcmp(key.data() + at, part.first, part.second * sizeof(double)) == 0;
      at += static_cast<size_t>(part.second);
    }
    if (same) return true;
    pending.resize(size);
    at = 0;
    for (const auto& part : parts) {
      if (part.second > 0) std::copy(part.first, part.first + part.second, pending.data() + at);
      at += static_cast<size_t>(part.second);
    }
    return false;
  }
  void store(const double* a, long na, const double* b, long nb) {
    key.swap(pending);
    first.assign(a, a + na);
    second.assign(b, b + nb);
  }
};

// The working storage of the constrained solves, like Pinocchio's Data: sized by a robot's first
// solve of each row count and reused, so that a field evaluation in contact allocates nothing.
struct Scratch {
  std::vector<Rigid> blocks;
  Mat J, W, frame_jacobian, MWt, A;
  Vec gamma, acc, rhs, lambda, zero, centred;
  Eigen::PartialPivLU<Mat> lu;
  // The Cholesky factor of M(q), from its upper triangle (Pinocchio's crba fills that one).
  legsim_small::SmallCholesky mass;
};

struct Robot {
  Model model;
  Data data;
  // The model as planar bodies, where it is one (planar_tree).
  PlanarTree planar;
  std::array<double, COUNTERS> counts{};
  SolveCache aba, kkt, gravity;
  Scratch scratch;
  // The contact point of each frame, from its origin in the world's axes (m): 0 for a point; for
  // a round frame (a sphere or a disc about the frame's origin) the offset to its point nearest
  // the ground, whose kinematics the functions below give (round_offset).
  std::vector<Eigen::Vector3d> offset;
  // A *moving* round frame stands on a terrain whose normal turns under it (a sine): its offset
  // -r n follows the normal at the terrain's point nearest its centre, which the model functions
  // find and set for each configuration (lsn_round_place). placed_at[id] is the q it was set at:
  // a call at another q has no offset for it and answers nan, a breakdown the run reports,
  // rather than the kinematics of a point the ball no longer touches with.
  std::vector<char> moving;
  std::vector<Vec> placed_at;
  // The coordinates that translate the whole robot (the prismatic joints hung from the world, one
  // after the other: a planar root's x and z). The world-convention algorithms express every
  // body's inertia at the world's origin, so their rounding grows with the square of the robot's
  // distance from it; they run with these coordinates at 0 (centred), which moves no velocity,
  // acceleration or force.
  std::vector<long> translations;
  explicit Robot(Model m)
      : model(std::move(m)),
        data(model),
        planar(planar_tree(model)),
        offset(model.frames.size(), Eigen::Vector3d::Zero()),
        moving(model.frames.size(), 0),
        placed_at(model.frames.size()) {
    scratch.frame_jacobian.setZero(6, model.nv);
    scratch.zero.setZero(model.nv);
    std::vector<char> translating(model.joints.size(), 0);
    translating[0] = 1;
    for (size_t j = 1; j < model.joints.size(); ++j) {
      const std::string kind = model.joints[j].shortname();
      if (translating[model.parents[j]] && kind.rfind("JointModelP", 0) == 0) {
        translating[j] = 1;
        translations.push_back(model.joints[j].idx_q());
      }
    }
  }
};

// q with the robot's translations at 0, in rb.scratch.centred (see Robot::translations).
const Vec& centred(Robot& rb, const double* q) {
  Vec& out = rb.scratch.centred;
  out = ConstMap(q, rb.model.nq);
  for (long i : rb.translations) out(i) = 0.0;
  return out;
}

// A round frame's contact point with a ground of normal n is its point nearest the ground,
// origin + d with d = -r n in the world's axes, which the model's description gives
// (legsim.robots.bridge.contacts.round_offset). It is not fixed in the body: the functions below
// give its position, the velocity v + w x d of the body's material point there (w x d lies
// along the ground: its normal part is the origin's), the derivative a + dw/dt x d of that
// velocity (d is constant in the world; no centripetal term), and the Jacobian of that velocity.
Eigen::Vector3d round_offset(const Robot& rb, pinocchio::FrameIndex id) { return rb.offset[id]; }

// Whether frame id's contact point is known at q: always for a fixed one; for a moving round
// frame, once lsn_round_place has placed it at this very q.
bool placed(const Robot& rb, const double* q, pinocchio::FrameIndex id) {
  if (!rb.moving[id]) return true;
  const Vec& at = rb.placed_at[id];
  return at.size() == rb.model.nq && std::equal(q, q + rb.model.nq, at.data());
}

// Whether every point block of `rigid` is placed at q (joint stops need no offset).
bool blocks_placed(const Robot& rb, const double* q, const std::vector<Rigid>& rigid) {
  for (const Rigid& r : rigid)
    if (r.kind != STOP && !placed(rb, q, static_cast<pinocchio::FrameIndex>(r.id))) return false;
  return true;
}

// Shift a world-aligned frame Jacobian (6, nv) to a round frame's contact point.
void shift_to_contact(const Robot& rb, pinocchio::FrameIndex id, Mat& Jf) {
  if (rb.offset[id].isZero(0.0)) return;
  const Eigen::Vector3d d = round_offset(rb, id);
  for (long j = 0; j < Jf.cols(); ++j) Jf.block<3, 1>(0, j) += Eigen::Vector3d(Jf.block<3, 1>(3, j)).cross(d);
}

// M(q) into rb.data.M (its upper triangle at least) and its Cholesky factor into
// rb.scratch.mass; with bias also h(q, v) into rb.data.nle. From the planar bodies where the model
// is planar (which give h at no extra cost), else from Pinocchio's crba (in the given convention)
// and RNEA. False where M is not positive definite (not a valid model at q).
bool factor_mass(Robot& rb, const ConstMap& q, const ConstMap& v, pinocchio::Convention convention, bool bias) {
  if (rb.planar.valid) {
    planar_dynamics(rb.planar, q.data(), v.data(), rb.model.nv, rb.data.M, rb.data.nle);
  } else {
    pinocchio::crba(rb.model, rb.data, q, convention);
    if (bias) pinocchio::nonLinearEffects(rb.model, rb.data, q, v);
  }
  return rb.scratch.mass.compute(rb.data.M);
}

// The unconstrained acceleration M^-1 (tau - h(q, v)) into acc, leaving M's Cholesky factor in
// rb.scratch.mass (and, for a model that is not planar, in the WORLD convention, the joint
// Jacobians in rb.data.J); false, acc all nan, where M is not positive definite (not a valid model
// at q). For the small models the bridge builds, M and h (planar_dynamics, else crba and RNEA's
// bias forces) and a dense Cholesky cost less than ABA, and the factor serves the constrained
// solve's M^-1 W^T too.
bool forward_dynamics(Robot& rb, const ConstMap& q, const ConstMap& v, const ConstMap& tau,
                      pinocchio::Convention convention, Vec& acc) {
  if (!factor_mass(rb, q, v, convention, true)) {  // the run's breakdown says so
    acc.setConstant(q.size(), std::numeric_limits<double>::quiet_NaN());
    return false;
  }
  acc = tau - rb.data.nle;
  rb.scratch.mass.solveInPlace(acc);
  return true;
}

std::vector<std::unique_ptr<Robot>> robots;
std::mutex robots_mutex;

Robot& robot(long h) { return *robots[static_cast<size_t>(h)]; }

pinocchio::SE3 read_placement(const double* d) {
  Eigen::Matrix3d R;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) R(i, j) = d[3 * i + j];
  return pinocchio::SE3(R, Eigen::Vector3d(d[9], d[10], d[11]));
}

// The joint of a simple code (RX .. PZ); false for another code.
bool simple_joint(int code, JointModel& out) {
  switch (code) {
    case RX: out = Joints::JointModelRX(); return true;
    case RY: out = Joints::JointModelRY(); return true;
    case RZ: out = Joints::JointModelRZ(); return true;
    case PX: out = Joints::JointModelPX(); return true;
    case PY: out = Joints::JointModelPY(); return true;
    case PZ: out = Joints::JointModelPZ(); return true;
    default: return false;
  }
}

// A joint of the description as the library builds it: one simple joint, or a composite's
// parts (the planar root PX, PZ, RY) each a joint of its own, the first placed by the part's
// placement after the composite's, the others by their own. The chain is the composite's
// kinematics and, with the bodies between the parts massless, its dynamics; Pinocchio's
// algorithms run it several times faster than its composite joint, which builds its parts'
// motion subspaces anew at every pass.
struct Part {
  JointModel joint;
  pinocchio::SE3 placement;
};

// The parts of the joint at desc[k] (its code, then for a composite its count and each part's
// code and placement[12]), k moved past it; false for a bad description.
bool read_joint(const double* desc, long size, long& k, std::vector<Part>& out) {
  out.clear();
  if (k + 1 > size) return false;
  const int code = static_cast<int>(desc[k++]);
  if (code != COMPOSITE) {
    out.push_back(Part{JointModel(), pinocchio::SE3::Identity()});
    return simple_joint(code, out.back().joint);
  }
  if (k + 1 > size) return false;
  // The count is checked as a double: casting a huge or nan one to long is undefined, and
  // k + 13 * parts could overflow past the bound.
  const double count = desc[k++];
  if (!(count >= 1.0 && count <= static_cast<double>(size - k) / 13.0)) return false;
  const long parts = static_cast<long>(count);
  for (long i = 0; i < parts; ++i, k += 13) {
    out.push_back(Part{JointModel(), read_placement(desc + k + 1)});
    if (!simple_joint(static_cast<int>(desc[k]), out.back().joint)) return false;
  }
  return true;
}

// The n blocks of desc (kind, id, sign, rows) into out, whose storage is reused.
void read_rigid(long n, const double* desc, std::vector<Rigid>& out) {
  out.resize(static_cast<size_t>(n));
  for (long i = 0; i < n; ++i)
    out[i] = Rigid{static_cast<int>(desc[4 * i]), static_cast<int>(desc[4 * i + 1]), desc[4 * i + 2],
                   static_cast<int>(desc[4 * i + 3])};
}

int total_rows(const std::vector<Rigid>& rigid) {
  int rows = 0;
  for (const Rigid& r : rigid) rows += r.rows;
  return rows;
}

// What the constraint rows read of a contact frame: its contact point's world-aligned Jacobian
// (into Jf, Pinocchio's 6-row layout: linear rows 0-2, angular rows 3-5), the classical
// acceleration of its origin at zero joint acceleration (with drift; 0 without) and its origin's
// velocity (m/s), both (x, y, z) in the world's axes.
struct ContactMotion {
  Eigen::Vector3d acc = Eigen::Vector3d::Zero(), origin_velocity = Eigen::Vector3d::Zero();
};

// ContactMotion from Pinocchio's kinematics, run at (q, v, 0) by the caller.
ContactMotion pinocchio_contact(Robot& rb, pinocchio::FrameIndex frame, bool drift, Mat& Jf) {
  ContactMotion out;
  Jf.setZero();
  pinocchio::getFrameJacobian(rb.model, rb.data, frame, pinocchio::LOCAL_WORLD_ALIGNED, Jf);
  shift_to_contact(rb, frame, Jf);
  if (drift) {
    const pinocchio::Motion motion =
        pinocchio::getFrameClassicalAcceleration(rb.model, rb.data, frame, pinocchio::LOCAL_WORLD_ALIGNED);
    out.acc = motion.linear() + motion.angular().cross(round_offset(rb, frame));
  }
  out.origin_velocity = pinocchio::getFrameVelocity(rb.model, rb.data, frame, pinocchio::LOCAL_WORLD_ALIGNED).linear();
  return out;
}

// ContactMotion of a planar robot, from its planar frames at (q, v): in the plane a body's turn
// has no angular acceleration at zero joint acceleration, so its origin's classical acceleration
// is its joint frame's less the centripetal w^2 r, and the contact point's (a round frame's,
// offset from the origin) the origin's.
ContactMotion planar_contact(Robot& rb, const ConstMap& q, const ConstMap& v, pinocchio::FrameIndex frame, Mat& Jf) {
  PlanarTree& tree = rb.planar;
  const long n = rb.model.nv;
  frames_at(tree, q.data(), v.data(), n, false);
  const long joint = tree.points[frame].joint;
  const PlanarTree::Frame& F = tree.frames[static_cast<size_t>(joint)];
  const std::array<double, 2> p = planar_point(tree, static_cast<long>(frame), round_offset(rb, frame));
  const std::array<double, 2> o = planar_point(tree, static_cast<long>(frame), Eigen::Vector3d::Zero());
  Jf.setZero();
  planar_columns(tree, joint, p[0], p[1], [&Jf](long c, const std::array<double, 3>& column) {
    Jf(0, c) = column[0];
    Jf(2, c) = column[1];
    Jf(4, c) = column[2];
  });
  const double w2 = F.w * F.w;
  const std::array<double, 2> velocity = F.velocity_at(o[0], o[1]);
  ContactMotion out;
  out.acc = Eigen::Vector3d(F.ax - w2 * (o[0] - F.ox), 0.0, F.az - w2 * (o[1] - F.oz));
  out.origin_velocity = Eigen::Vector3d(velocity[0], 0.0, velocity[1]);
  return out;
}

// The stacked constraint Jacobian (rows, nv); with drift also dJ/dt v (the classical
// acceleration of each point at zero joint acceleration), and the force directions W (J but on
// slipping points' rows). A contact frame's motion from the planar frames of a planar robot
// (planar_contact), else from Pinocchio's kinematics at (q, v, 0). slopes: null (the ground is level
// under every point), or (h', h'', bias) per block: the terrain's slope dh/dx and curvature
// d2h/dx2 under the point, whose rows are then along the terrain's tangent t = (1, h') / s and
// normal n = (-h', 1) / s, s = sqrt(1 + h'^2), and for a moving round frame a term (m/s^2)
// added to its normal row's drift, which steers its centre back onto the curve r from the
// terrain (0 elsewhere; a point on a level ground takes the rows x and z as
// before, bit for bit). jacobians_ready (Pinocchio's kinematics): data.J already holds the joint
// Jacobians at q (a crba in the WORLD convention fills them), which spares a second pass.
void constraint_rows(Robot& rb, const ConstMap& q, const ConstMap& v, const std::vector<Rigid>& rigid,
                     const double* slopes, bool drift, bool jacobians_ready, Mat& J, Vec& gamma, Mat& W) {
  const Model& model = rb.model;
  Data& data = rb.data;
  const int rows = total_rows(rigid);
  J.setZero(rows, model.nv);
  W.setZero(rows, model.nv);
  gamma.setZero(rows);
  bool points = false;
  for (const Rigid& r : rigid) points = points || r.kind != STOP;
  if (points && !rb.planar.valid) {
    pinocchio::forwardKinematics(model, data, q, v, rb.scratch.zero);
    if (!jacobians_ready) pinocchio::computeJointJacobians(model, data, q);
  }
  Mat& Jf = rb.scratch.frame_jacobian;
  int i = 0;
  for (size_t b = 0; b < rigid.size(); ++b) {
    const Rigid& r = rigid[b];
    if (r.kind == STOP) {
      J(i, r.id) = r.sign;
      W(i, r.id) = r.sign;
      i += r.rows;
      continue;
    }
    const auto frame = static_cast<pinocchio::FrameIndex>(r.id);
    const ContactMotion motion = rb.planar.valid ? planar_contact(rb, q, v, frame, Jf) : pinocchio_contact(rb, frame, drift, Jf);
    const double slope = slopes == nullptr ? 0.0 : slopes[3 * b];
    // A point's d2h/dx2; a moving round frame's instead the curvature K (1/m) of the level set of
    // its centre's distance to the terrain (the offset curve): rolling or sliding, the centre keeps
    // that distance, whose second derivative has the term K (t . v_centre)^2.
    const double curvature = slopes == nullptr ? 0.0 : slopes[3 * b + 1];
    const double bias = slopes == nullptr ? 0.0 : slopes[3 * b + 2];
    const bool rolling = rb.moving[frame] != 0;
    const Eigen::Vector3d acc = drift ? motion.acc : Eigen::Vector3d::Zero();
    if (slope == 0.0 && curvature == 0.0 && bias == 0.0) {
      if (r.rows == 2) {
        J.row(i) = Jf.row(0);
        J.row(i + 1) = Jf.row(2);
        gamma(i) = acc(0);
        gamma(i + 1) = acc(2);
      } else {
        J.row(i) = Jf.row(2);
        gamma(i) = acc(2);
      }
      W.middleRows(i, r.rows) = J.middleRows(i, r.rows);
      if (r.kind == SLIPPING_POINT) W.row(i) -= r.sign * Jf.row(0);
    } else {
      const double s = std::sqrt(1.0 + slope * slope);
      const Eigen::RowVectorXd tangent = (Jf.row(0) + slope * Jf.row(2)) / s;
      const Eigen::RowVectorXd normal = (Jf.row(2) - slope * Jf.row(0)) / s;
      const int n_row = i + r.rows - 1;
      if (r.rows == 2) {  // a pinned point: its acceleration is 0, in any axes
        J.row(i) = tangent;
        J.row(i + 1) = normal;
        gamma(i) = (acc(0) + slope * acc(2)) / s;
        gamma(i + 1) = (acc(2) - slope * acc(0)) / s;
      } else if (rolling) {
        J.row(i) = normal;
        gamma(i) = (acc(2) - slope * acc(0)) / s;
      } else {  // z - h(x) = 0 held: its second derivative has the curvature term -h'' vx^2
        J.row(i) = normal;
        const double vx = drift ? motion.origin_velocity(0) : 0.0;
        gamma(i) = (acc(2) - slope * acc(0) - curvature * vx * vx) / s;
      }
      if (rolling && drift) {
        const Eigen::Vector3d& centre = motion.origin_velocity;
        const double along = (centre(0) + slope * centre(2)) / s;
        gamma(n_row) += curvature * along * along + bias;
      }
      W.middleRows(i, r.rows) = J.middleRows(i, r.rows);
      if (r.kind == SLIPPING_POINT) W.row(i) -= r.sign * tangent;
    }
    i += r.rows;
  }
}

// M^-1 as a full symmetric matrix, from M's Cholesky factor (factor_mass), its lower triangle
// the upper one's mirror; all nan where M is not positive definite.
Mat minverse(Robot& rb, const ConstMap& q) {
  const long n = rb.model.nv;
  Mat Minv = Mat::Identity(n, n);
  if (!factor_mass(rb, q, ConstMap(rb.scratch.zero.data(), n), pinocchio::Convention::LOCAL, false)) {
    Minv.setConstant(std::numeric_limits<double>::quiet_NaN());
    return Minv;
  }
  rb.scratch.mass.solveInPlace(Minv);
  Minv.triangularView<Eigen::StrictlyLower>() = Minv.transpose().triangularView<Eigen::StrictlyLower>();
  return Minv;
}

// A pivot or eigenvalue below this share of the largest is zero: the matrix is singular to rounding.
constexpr double kSingular = 1e-12;
// The largest residual (relative to 1 + max |b|) of a least-norm solve whose b is in A's range.
constexpr double kConsistent = 1e-8;

// A contact's forces over the rows of a solve, y(tangent) and y(normal), are inside its cone
// where y(normal) >= 0 and |y(tangent)| <= mu y(normal); with tangent < 0 (a single normal row)
// or mu < 0 (no friction bound), where y(normal) >= 0.
struct Cone {
  long tangent, normal;
  double mu;
};
using Cones = std::vector<Cone>;

// The cone of each constraint block: a stuck point's own friction coefficient is its sign.
Cones cones_of(const std::vector<Rigid>& rigid) {
  Cones cones;
  long row = 0;
  for (const Rigid& r : rigid) {
    if (r.kind == POINT && r.rows == 2)
      cones.push_back({row, row + 1, r.sign});
    else
      cones.push_back({-1, row + r.rows - 1, -1.0});
    row += r.rows;
  }
  return cones;
}

// Among the solutions y + Z c of rows that depend on one another (Z: orthonormal null vectors of
// A, (m, d); y the least-norm one), the one that loads each stuck contact's friction in
// proportion to its capacity mu y(normal): the least sum of y(tangent)^2 / (mu y(normal)) over the
// friction cones, the other rows weighted 1 / (1 + max |y|). Where the normal forces do not depend
// on c, as at two stuck corners of one body, every stuck contact then uses the same share of its
// cone: the support holds wherever some share of it is inside the cones (Coulomb's law has a
// statically indeterminate body stick then), and its contacts' slip guards reach 0 together,
// where the body as a whole slips. The least-norm share alone leaves the cone of the less loaded
// contact first: a block on a slope below its friction angle would slip. A second pass weighs by
// the normals the first moved. y is kept where the weighted rows leave the choice open.
void share_by_capacity(const Mat& Z, const Cones& cones, Vec& y) {
  bool friction = false;
  for (const Cone& k : cones) friction = friction || (k.tangent >= 0 && k.mu > 0.0);
  if (Z.cols() == 0 || !friction) return;
  const double scale = 1.0 + y.cwiseAbs().maxCoeff();
  for (int pass = 0; pass < 2; ++pass) {
    Vec weight = Vec::Constant(y.size(), 1.0 / scale);
    for (const Cone& k : cones)
      if (k.tangent >= 0 && k.mu > 0.0) weight(k.tangent) = 1.0 / (k.mu * std::max(y(k.normal), kSingular * scale));
    const Mat ZtW = Z.transpose() * weight.asDiagonal();
    const Eigen::LDLT<Mat> normal(ZtW * Z);
    if (normal.info() != Eigen::Success || !(normal.rcond() >= kSingular)) return;
    y += Z * normal.solve(-(ZtW * y));
  }
}

// The least-norm solution of A y = b for a symmetric positive semidefinite A: the sum over the
// eigenvalues above kSingular of the largest of (v . b / lambda) v. Where A is singular, as for
// two stuck points of one rigid body (four rows on its three degrees of freedom: a statically
// indeterminate support), the forces or impulses are not unique, and this picks the smallest
// (an equal share at a symmetric support), then shared by the contacts' capacities (share_by_capacity).
void least_norm_solve(const Mat& A, const Vec& b, Vec& y, const Cones& cones) {
  Eigen::SelfAdjointEigenSolver<Mat> eigen(A);
  const Vec& values = eigen.eigenvalues();
  const double cut = kSingular * values.cwiseAbs().maxCoeff();
  y.setZero(A.rows());
  long nulls = 0;
  for (long i = 0; i < values.size(); ++i) {
    if (values(i) > cut)
      y += (eigen.eigenvectors().col(i).dot(b) / values(i)) * eigen.eigenvectors().col(i);
    else
      ++nulls;
  }
  // The eigenvalues ascend: the null vectors are the first columns.
  share_by_capacity(eigen.eigenvectors().leftCols(nulls), cones, y);
}

// Whether y meets A y = b to kConsistent (relative to 1 + max |b|): b lies in a singular A's range.
bool meets(const Mat& A, const Vec& y, const Vec& b) {
  return (A * y - b).cwiseAbs().maxCoeff() <= kConsistent * (1.0 + b.cwiseAbs().maxCoeff());
}

// Solve A y = b for the small SPD Delassus matrix; one and two rows in closed form; lu is the
// reused factorisation of larger ones. With least_norm, a singular A takes the least-norm
// solution, shared by its blocks' capacities (least_norm_solve).
void solve_small(const Mat& A, const Vec& b, Eigen::PartialPivLU<Mat>& lu, Vec& y, const std::vector<Rigid>& blocks,
                 bool least_norm = false) {
  y.resize(A.rows());
  if (A.rows() == 1) {
    y(0) = b(0) / A(0, 0);
  } else if (A.rows() == 2) {
    const double det = A(0, 0) * A(1, 1) - A(0, 1) * A(1, 0);
    y(0) = (A(1, 1) * b(0) - A(0, 1) * b(1)) / det;
    y(1) = (A(0, 0) * b(1) - A(1, 0) * b(0)) / det;
  } else {
    lu.compute(A);
    if (least_norm && !(lu.rcond() >= kSingular)) {  // a zero pivot makes the estimate nan
      least_norm_solve(A, b, y, cones_of(blocks));
      return;
    }
    y = lu.solve(b);
    // The estimate can miss an exact zero pivot (two stuck corners of one body: two identical
    // rows) when b has a rounding's share outside A's range (a 1e-15 rad/s spin left by an
    // impact), and the solve divides by it: the least-norm solution is the one meant.
    if (least_norm && !y.allFinite()) least_norm_solve(A, b, y, cones_of(blocks));
  }
}

bool slipping(const std::vector<Rigid>& rigid) {
  for (const Rigid& r : rigid)
    if (r.kind == SLIPPING_POINT) return true;
  return false;
}

// Whether every diagonal entry of a Delassus matrix with slipping rows is positive: where one is
// not, pushing on a slipping point would drive it into the ground (the Painleve paradox).
bool positive_diagonal(const Mat& A) {
  return !(A.diagonal().array() <= 1e-12 * A.cwiseAbs().maxCoeff()).any();
}

bool regular(const Mat& A) {
  const double scale = A.cwiseAbs().maxCoeff();
  return std::abs(A.determinant()) > 1e-12 * std::pow(scale, static_cast<double>(A.rows()));
}

// The orthonormal null vectors (columns) of A: its right singular vectors whose singular values
// are at most kSingular of the largest.
Mat null_vectors(const Mat& A) {
  Eigen::JacobiSVD<Mat> svd(A, Eigen::ComputeFullV);
  const Vec& sigma = svd.singularValues();
  long rank = 0;
  while (rank < sigma.size() && sigma(rank) > kSingular * sigma(0)) ++rank;
  return svd.matrixV().rightCols(A.cols() - rank);
}

// Solve A y = b for a singular Delassus matrix A = J M^-1 W^T with sliding rows (W = J - s mu t
// on them; MWt = M^-1 W^T, (n, m)): rows that depend on one another, as two stuck corners of one
// body beside a slipping contact do, or a slipping point whose normal row the other rows already
// hold. Where A's null vectors are null vectors of MWt too (rank A = rank MWt), every solution
// gives the same motion MWt y, and this takes the least-norm y (as least_norm_solve does without
// sliding rows), shared by the stuck contacts' capacities (share_by_capacity). Returns false
// where no y solves the rows (b outside A's range) or the motion is not unique: the Painleve
// paradox.
bool sliding_solve(const Mat& A, const Vec& b, const Mat& MWt, Vec& y, const Cones& cones) {
  Eigen::CompleteOrthogonalDecomposition<Mat> rows(A);
  rows.setThreshold(kSingular);
  Eigen::ColPivHouseholderQR<Mat> motion(MWt);
  motion.setThreshold(kSingular);
  if (rows.rank() != motion.rank()) return false;
  y = rows.solve(b);
  if (!y.allFinite() || !meets(A, y, b)) return false;
  share_by_capacity(null_vectors(A), cones, y);
  return true;
}

// The constraint forces s.lambda of s.A lambda = s.rhs: the least-norm ones where dependent rows
// make s.A singular (sliding_solve beside slipping rows); false where slipping rows have no unique
// forces (the Painleve paradox), the mode then being past its model's range.
bool constraint_forces(Scratch& s) {
  if (!slipping(s.blocks)) {
    solve_small(s.A, s.rhs, s.lu, s.lambda, s.blocks, true);
    return true;
  }
  if (!positive_diagonal(s.A)) return false;
  if (regular(s.A)) {
    solve_small(s.A, s.rhs, s.lu, s.lambda, s.blocks);
    return true;
  }
  return sliding_solve(s.A, s.rhs, s.MWt, s.lambda, cones_of(s.blocks));
}

// lsn_frames of a planar robot: (x, z, vx, vz) of each frame's contact point, nan for a round
// frame not placed at q.
void planar_frames_at(Robot& rb, const double* q, const double* v, long count, const double* frames, double* out) {
  PlanarTree& tree = rb.planar;
  frames_at(tree, q, v, rb.model.nv, false);
  for (long i = 0; i < count; ++i) {
    const auto id = static_cast<pinocchio::FrameIndex>(frames[i]);
    if (!placed(rb, q, id)) {
      std::fill(out + 4 * i, out + 4 * i + 4, std::numeric_limits<double>::quiet_NaN());
      continue;
    }
    const std::array<double, 2> p = planar_point(tree, static_cast<long>(id), round_offset(rb, id));
    const std::array<double, 2> velocity = tree.frames[static_cast<size_t>(tree.points[id].joint)].velocity_at(p[0], p[1]);
    out[4 * i] = p[0];
    out[4 * i + 1] = p[1];
    out[4 * i + 2] = velocity[0];
    out[4 * i + 3] = velocity[1];
  }
}

// lsn_frame_jacobian of a planar robot (a placed frame): (x, z, Jacobian row x, row z).
void planar_jacobian(Robot& rb, const double* q, pinocchio::FrameIndex id, double* out) {
  PlanarTree& tree = rb.planar;
  const long n = rb.model.nv;
  frames_at(tree, q, rb.scratch.zero.data(), n, true);
  const std::array<double, 2> p = planar_point(tree, static_cast<long>(id), round_offset(rb, id));
  out[0] = p[0];
  out[1] = p[1];
  std::fill(out + 2, out + 2 + 2 * n, 0.0);
  planar_columns(tree, tree.points[id].joint, p[0], p[1], [out, n](long v, const std::array<double, 3>& column) {
    out[2 + v] = column[0];
    out[2 + n + v] = column[1];
  });
}

}  // namespace

// The C interface is the library's only export: everything else (Pinocchio's template code
// above) is compiled with hidden visibility (setup.py), so that its calls bind inside the
// library, without the procedure linkage table, and the compiler may inline them.
#pragma GCC visibility push(default)
extern "C" {

// Version of this C interface (bumped when a signature changes).
long lsn_version() { return kVersion; }

// Build a model from a flat description and return its handle (>= 0), or -1 on a bad
// description. Layout: [njoints-1, then per joint (code, [a composite's part count, then per
// part (code, placement[12])], parent, placement[12], mass, lever[3], inertia about the centre
// of mass[9]), nframes-1, then per frame
// (parent joint, placement[12]), gravity linear[3], the count of round frames, then per round
// frame (frame id, the contact point's offset from its origin along x and z)]. A placement is R
// row-major then p.
// Frames are added in order after the universe frame, so frame ids are the Python model's.
long lsn_create(const double* desc, long size) {
  Model model;
  long k = 0;
  auto need = [&](long n) { return k + n <= size; };
  if (!need(1)) return -1;
  const long joints = static_cast<long>(desc[k++]);
  // The library's index of each description joint (a composite's: its last part's).
  std::vector<pinocchio::JointIndex> index_of(1, 0);
  std::vector<Part> parts;
  for (long j = 0; j < joints; ++j) {
    if (!read_joint(desc, size, k, parts) || !need(26)) return -1;
    const int parent = static_cast<int>(desc[k]);
    const pinocchio::SE3 placement = read_placement(desc + k + 1);
    const double mass = desc[k + 13];
    const Eigen::Vector3d lever(desc[k + 14], desc[k + 15], desc[k + 16]);
    Eigen::Matrix3d I;
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) I(a, b) = desc[k + 17 + 3 * a + b];
    k += 26;
    if (parent < 0 || parent > j) return -1;
    pinocchio::JointIndex last = index_of[static_cast<size_t>(parent)];
    for (size_t i = 0; i < parts.size(); ++i) {
      const pinocchio::SE3 at = i == 0 ? placement * parts[i].placement : parts[i].placement;
      last = model.addJoint(last, parts[i].joint, at, "j" + std::to_string(j + 1) + "_" + std::to_string(i));
    }
    model.appendBodyToJoint(last, pinocchio::Inertia(mass, lever, I), pinocchio::SE3::Identity());
    index_of.push_back(last);
  }
  if (!need(1)) return -1;
  const long frames = static_cast<long>(desc[k++]);
  // Joints added their own frames; replace the list by the Python model's (universe kept).
  model.frames.resize(1);
  model.nframes = 1;
  for (long f = 0; f < frames; ++f) {
    if (!need(13)) return -1;
    const int parent = static_cast<int>(desc[k]);
    if (parent < 0 || parent > joints) return -1;
    model.addFrame(Model::Frame("f" + std::to_string(f + 1), index_of[static_cast<size_t>(parent)], 0,
                                    read_placement(desc + k + 1), pinocchio::OP_FRAME),
                   false);
    k += 13;
  }
  if (!need(4)) return -1;
  model.gravity.linear(Eigen::Vector3d(desc[k], desc[k + 1], desc[k + 2]));
  model.gravity.angular(Eigen::Vector3d::Zero());
  k += 3;
  // The round frames: count, then (frame id, offset x, offset z) triples, the offset finite and
  // not zero; checked as doubles (see above).
  const double rounds = desc[k++];
  if (!(rounds >= 0.0 && rounds <= static_cast<double>(size - k) / 3.0)) return -1;
  auto rb = std::make_unique<Robot>(std::move(model));
  for (long i = 0; i < static_cast<long>(rounds); ++i, k += 3) {
    const double frame = desc[k], dx = desc[k + 1], dz = desc[k + 2];
    const bool valid = std::isfinite(dx) && std::isfinite(dz) && (dx != 0.0 || dz != 0.0);
    if (!(frame >= 1.0 && frame <= static_cast<double>(frames) && valid)) return -1;
    rb->offset[static_cast<size_t>(frame)] = Eigen::Vector3d(dx, 0.0, dz);
  }
  std::lock_guard<std::mutex> lock(robots_mutex);
  robots.push_back(std::move(rb));
  return static_cast<long>(robots.size() - 1);
}

long lsn_nv(long h) { return robot(h).model.nv; }

// 1 where the model's M and h come from its planar bodies (planar_dynamics), 0 where from
// Pinocchio's crba and RNEA.
long lsn_planar(long h) { return robot(h).planar.valid ? 1 : 0; }

// a = M^-1 (tau - h(q, v)): the unconstrained joint acceleration under applied forces tau (the
// forward dynamics that Pinocchio's ABA also computes; counted in the ABA slot).
void lsn_aba(long h, const double* q, const double* v, const double* tau, double* a) {
  Robot& rb = robot(h);
  const long n = rb.model.nv;
  if (rb.aba.hit({{q, n}, {v, n}, {tau, n}})) {
    rb.counts[CACHE_HITS] += 1;
    std::copy(rb.aba.first.begin(), rb.aba.first.end(), a);
    return;
  }
  rb.counts[ABA] += 1;
  const ConstMap qm(centred(rb, q).data(), n);
  forward_dynamics(rb, qm, ConstMap(v, n), ConstMap(tau, n), pinocchio::Convention::LOCAL, rb.scratch.acc);
  OutMap(a, n) = rb.scratch.acc;
  rb.aba.store(a, n, a, 0);
}

// Positions and world-aligned linear velocities of frames: out[4 i .. 4 i + 3] = (x, z, vx, vz)
// of frames[i], from one kinematics pass at (q, v).
void lsn_frames(long h, const double* q, const double* v, long count, const double* frames, double* out) {
  Robot& rb = robot(h);
  const long n = rb.model.nv;
  rb.counts[KINEMATICS] += 1;
  if (rb.planar.valid) {
    planar_frames_at(rb, q, v, count, frames, out);
    return;
  }
  pinocchio::forwardKinematics(rb.model, rb.data, ConstMap(q, n), ConstMap(v, n));
  for (long i = 0; i < count; ++i) {
    const auto id = static_cast<pinocchio::FrameIndex>(frames[i]);
    if (!placed(rb, q, id)) {
      std::fill(out + 4 * i, out + 4 * i + 4, std::numeric_limits<double>::quiet_NaN());
      continue;
    }
    const Eigen::Vector3d d = round_offset(rb, id);
    const Eigen::Vector3d p = pinocchio::updateFramePlacement(rb.model, rb.data, id).translation() + d;
    const pinocchio::Motion motion = pinocchio::getFrameVelocity(rb.model, rb.data, id, pinocchio::LOCAL_WORLD_ALIGNED);
    const Eigen::Vector3d w = motion.linear() + motion.angular().cross(d);
    out[4 * i] = p(0);
    out[4 * i + 1] = p(2);
    out[4 * i + 2] = w(0);
    out[4 * i + 3] = w(2);
  }
}

// A frame at q: out = (x, z, Jacobian row x (nv), Jacobian row z (nv)), the Jacobian world-aligned.
void lsn_frame_jacobian(long h, const double* q, long frame, double* out) {
  Robot& rb = robot(h);
  const long n = rb.model.nv;
  const auto id = static_cast<pinocchio::FrameIndex>(frame);
  if (!placed(rb, q, id)) {
    std::fill(out, out + 2 + 2 * n, std::numeric_limits<double>::quiet_NaN());
    return;
  }
  rb.counts[JACOBIANS] += 1;
  if (rb.planar.valid) {
    planar_jacobian(rb, q, id, out);
    return;
  }
  Mat& Jf = rb.scratch.frame_jacobian;  // reused: a stance spring's force is asked at every evaluation
  Jf.setZero(6, n);
  pinocchio::computeFrameJacobian(rb.model, rb.data, ConstMap(q, n), id, pinocchio::LOCAL_WORLD_ALIGNED, Jf);
  shift_to_contact(rb, id, Jf);
  const Eigen::Vector3d p = rb.data.oMf[id].translation() + round_offset(rb, id);
  out[0] = p(0);
  out[1] = p(2);
  for (long j = 0; j < n; ++j) {
    out[2 + j] = Jf(0, j);
    out[2 + n + j] = Jf(2, j);
  }
}

// The angular momentum (y component, N m s) about a frame's origin P at (q, v):
// H_P = (angular momentum about the centre of mass) + (c - P) x m v_c; out = (H_P, P_x, P_z).
void lsn_momentum_about(long h, const double* q, const double* v, long frame, double* out) {
  Robot& rb = robot(h);
  const long n = rb.model.nv;
  const ConstMap qm(q, n), vm(v, n);
  pinocchio::computeCentroidalMomentum(rb.model, rb.data, qm, vm);
  pinocchio::centerOfMass(rb.model, rb.data, qm, vm);
  pinocchio::forwardKinematics(rb.model, rb.data, qm);
  const Eigen::Vector3d tip = pinocchio::updateFramePlacement(rb.model, rb.data, static_cast<pinocchio::FrameIndex>(frame))
                       .translation();
  const Eigen::Vector3d r = rb.data.com[0] - tip;
  const Eigen::Vector3d p = rb.data.mass[0] * rb.data.vcom[0];
  out[0] = rb.data.hg.angular()(1) + (r(2) * p(0) - r(0) * p(2));
  out[1] = tip(0);
  out[2] = tip(2);
}

// A frame's world-aligned linear velocity and classical acceleration at (q, v, a):
// out = (vx, vz, ax, az) (m/s, m/s^2).
void lsn_frame_motion(long h, const double* q, const double* v, const double* a, long frame, double* out) {
  Robot& rb = robot(h);
  const long n = rb.model.nv;
  const auto id = static_cast<pinocchio::FrameIndex>(frame);
  if (!placed(rb, q, id)) {
    std::fill(out, out + 4, std::numeric_limits<double>::quiet_NaN());
    return;
  }
  rb.counts[KINEMATICS] += 1;
  pinocchio::forwardKinematics(rb.model, rb.data, ConstMap(q, n), ConstMap(v, n), ConstMap(a, n));
  pinocchio::updateFramePlacement(rb.model, rb.data, id);
  const Eigen::Vector3d d = round_offset(rb, id);
  const pinocchio::Motion velocity = pinocchio::getFrameVelocity(rb.model, rb.data, id, pinocchio::LOCAL_WORLD_ALIGNED);
  const pinocchio::Motion accel = pinocchio::getFrameClassicalAcceleration(rb.model, rb.data, id, pinocchio::LOCAL_WORLD_ALIGNED);
  const Eigen::Vector3d w = velocity.linear() + velocity.angular().cross(d);
  const Eigen::Vector3d acc = accel.linear() + accel.angular().cross(d);
  out[0] = w(0);
  out[1] = w(2);
  out[2] = acc(0);
  out[3] = acc(2);
}

// The generalised gravity g(q) (nv): the joint forces that hold the robot still against gravity.
void lsn_gravity(long h, const double* q, double* out) {
  Robot& rb = robot(h);
  const long n = rb.model.nv;
  if (rb.gravity.hit({{q, n}})) {
    rb.counts[CACHE_HITS] += 1;
    std::copy(rb.gravity.first.begin(), rb.gravity.first.end(), out);
    return;
  }
  OutMap(out, n) = pinocchio::computeGeneralizedGravity(rb.model, rb.data, ConstMap(q, n));
  rb.gravity.store(out, n, out, 0);
}

// The joint-space inertia matrix M(q) (nv, nv), row-major, both triangles filled.
void lsn_crba(long h, const double* q, double* out) {
  Robot& rb = robot(h);
  const long n = rb.model.nv;
  pinocchio::crba(rb.model, rb.data, ConstMap(q, n));
  Mat M = rb.data.M;
  M.triangularView<Eigen::StrictlyLower>() = M.transpose().triangularView<Eigen::StrictlyLower>();
  for (long i = 0; i < n; ++i)
    for (long j = 0; j < n; ++j) out[n * i + j] = M(i, j);
}

// The constrained (KKT) dynamics of the rigid contacts `rigid` (count blocks of
// (kind, id, sign, rows)) under applied forces tau: acceleration a (nv) and the constraint
// forces lam (rows), the normal force of each block last and >= 0 when it pushes. slopes: null
// on level ground, else the terrain's (slope, curvature, bias) under each block (constraint_rows).
void lsn_constrained(long h, const double* q, const double* v, const double* tau, long count, const double* rigid,
                     const double* slopes, double* a, double* lam) {
  Robot& rb = robot(h);
  const long n = rb.model.nv;
  if (rb.kkt.hit({{q, n}, {v, n}, {tau, n}, {rigid, 4 * count}, {slopes, slopes == nullptr ? 0 : 3 * count}})) {
    rb.counts[CACHE_HITS] += 1;
    std::copy(rb.kkt.first.begin(), rb.kkt.first.end(), a);
    std::copy(rb.kkt.second.begin(), rb.kkt.second.end(), lam);
    return;
  }
  Scratch& s = rb.scratch;
  read_rigid(count, rigid, s.blocks);
  if (!blocks_placed(rb, q, s.blocks)) {
    OutMap(a, n).setConstant(std::numeric_limits<double>::quiet_NaN());
    OutMap(lam, total_rows(s.blocks)).setConstant(std::numeric_limits<double>::quiet_NaN());
    return;
  }
  const ConstMap qm(centred(rb, q).data(), n), vm(v, n);
  rb.counts[ABA] += 1;
  rb.counts[KKT] += 1;
  // Pinocchio's world-convention crba also leaves the joint Jacobians the constraint rows read.
  if (!forward_dynamics(rb, qm, vm, ConstMap(tau, n), pinocchio::Convention::WORLD, s.acc)) {
    OutMap(a, n) = s.acc;
    OutMap(lam, total_rows(s.blocks)).setConstant(std::numeric_limits<double>::quiet_NaN());
    return;
  }
  constraint_rows(rb, qm, vm, s.blocks, slopes, true, true, s.J, s.gamma, s.W);
  s.MWt = s.W.transpose();
  s.mass.solveInPlace(s.MWt);
  // Coefficient-wise products: a few rows, and Eigen's general product would first choose its
  // blocking for large ones.
  s.A.noalias() = s.J.lazyProduct(s.MWt);
  s.rhs.noalias() = s.J.lazyProduct(s.acc);
  s.rhs = -(s.rhs + s.gamma);
  if (!constraint_forces(s)) {
    OutMap(a, n).setConstant(std::numeric_limits<double>::quiet_NaN());
    OutMap(lam, s.A.rows()).setConstant(std::numeric_limits<double>::quiet_NaN());
  } else {
    s.acc.noalias() += s.MWt.lazyProduct(s.lambda);
    OutMap(a, n) = s.acc;
    OutMap(lam, s.lambda.size()) = s.lambda;
  }
  rb.kkt.store(a, n, lam, s.A.rows());
}

// The generalised Newton impact: v+ = v + M^-1 J^T Lambda, Lambda = (J M^-1 J^T)^-1 (-(1 + c) J v),
// with the restitution c of each block (coeff, one per block) on its rows; the impulses Lambda
// (one per row, N s or N m s) into impulse_out unless it is null; slopes as for lsn_constrained.
void lsn_impact(long h, const double* q, const double* v, long count, const double* rigid, const double* slopes,
                const double* coeff, double* v_out, double* impulse_out) {
  Robot& rb = robot(h);
  const long n = rb.model.nv;
  const ConstMap qm(centred(rb, q).data(), n), vm(v, n);
  Scratch& s = rb.scratch;
  read_rigid(count, rigid, s.blocks);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  if (!blocks_placed(rb, q, s.blocks)) {
    OutMap(v_out, n).setConstant(nan);
    if (impulse_out != nullptr) OutMap(impulse_out, total_rows(s.blocks)).setConstant(nan);
    return;
  }
  rb.counts[IMPACTS] += 1;
  constraint_rows(rb, qm, vm, s.blocks, slopes, false, false, s.J, s.gamma, s.W);
  if (!factor_mass(rb, qm, vm, pinocchio::Convention::LOCAL, false)) {
    OutMap(v_out, n).setConstant(nan);
    if (impulse_out != nullptr) OutMap(impulse_out, s.J.rows()).setConstant(nan);
    return;
  }
  s.MWt = s.J.transpose();  // M^-1 J^T
  s.mass.solveInPlace(s.MWt);
  s.rhs.noalias() = s.J.lazyProduct(vm);  // J v, then -(1 + c) J v with each block's restitution c
  int i = 0;
  for (long b = 0; b < count; ++b)
    for (int r = 0; r < s.blocks[b].rows; ++r, ++i) s.rhs(i) *= -(1.0 + coeff[b]);
  s.A.noalias() = s.J.lazyProduct(s.MWt);
  solve_small(s.A, s.rhs, s.lu, s.lambda, s.blocks, !slipping(s.blocks));
  OutMap(v_out, n) = vm + s.MWt.lazyProduct(s.lambda);
  if (impulse_out != nullptr) OutMap(impulse_out, s.lambda.size()) = s.lambda;
}

// The inverse of the joint-space inertia matrix M(q)^-1 (nv, nv), row-major, both triangles filled.
void lsn_minverse(long h, const double* q, double* out) {
  Robot& rb = robot(h);
  const long n = rb.model.nv;
  const Mat Minv = minverse(rb, ConstMap(q, n));
  for (long i = 0; i < n; ++i)
    for (long j = 0; j < n; ++j) out[n * i + j] = Minv(i, j);
}

// Solve the small system A y = b (m rows, A row-major) of the bridge's frictional impacts into
// out[0 .. m-1], and out[m] = 1 where it is solved, 0 where not. A singular A (its LU's
// reciprocal condition below kSingular) takes with least_norm (no sliding rows: A symmetric
// positive semidefinite) the least-norm y; without, sliding_solve's, MWt (n, m) row-major being
// M^-1 W^T; either shared by the capacities of the cones (count triples (tangent row, normal
// row, mu), the tangent row -1 for a normal row alone; share_by_capacity). Not solved: A or b
// not finite, b outside A's range (the residual beyond kConsistent), or a motion MWt y that is
// not unique (the Painleve case).
void lsn_solve(long m, const double* A, const double* b, long least_norm, long n, const double* MWt, long count,
               const double* cones, double* out) {
  using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  const Mat a = Eigen::Map<const RowMajor>(A, m, m);
  const Vec rhs = ConstMap(b, m);
  out[m] = 0.0;
  if (!a.allFinite() || !rhs.allFinite()) return;
  Cones rows_cones;
  for (long k = 0; k < count; ++k)
    rows_cones.push_back({static_cast<long>(cones[3 * k]), static_cast<long>(cones[3 * k + 1]), cones[3 * k + 2]});
  Vec y;
  Eigen::PartialPivLU<Mat> lu(a);
  if (lu.rcond() >= kSingular) {
    y = lu.solve(rhs);
  } else if (least_norm == 0) {
    if (!sliding_solve(a, rhs, Eigen::Map<const RowMajor>(MWt, n, m), y, rows_cones)) return;
  } else {
    least_norm_solve(a, rhs, y, rows_cones);
    if (!meets(a, y, rhs)) return;
  }
  if (!y.allFinite()) return;
  OutMap(out, m) = y;
  out[m] = 1.0;
}

// Make round frame `frame` moving (see Robot::moving): from now on its offset is set for each
// configuration by lsn_round_place, and calls at a q it was not placed at answer nan. A frame
// that is not round, or out of range, is left as it is.
void lsn_round_moving(long h, long frame) {
  Robot& rb = robot(h);
  if (frame <= 0 || frame >= static_cast<long>(rb.offset.size()) || rb.offset[frame].isZero(0.0)) return;
  rb.moving[frame] = 1;
  rb.placed_at[frame].resize(0);
}

// The offset (dx, dz) (m, world axes) of moving round frame `frame` at q: -r n, n the terrain's
// normal at its point nearest the frame's centre (legsim.heights.nearest). Ignored for a frame
// that is not moving.
void lsn_round_place(long h, const double* q, long frame, double dx, double dz) {
  Robot& rb = robot(h);
  if (frame <= 0 || frame >= static_cast<long>(rb.offset.size()) || !rb.moving[frame]) return;
  rb.offset[frame] = Eigen::Vector3d(dx, 0.0, dz);
  rb.placed_at[frame] = ConstMap(q, rb.model.nq);
}

// Add `amount` to the robot's counter `slot` (a count the model functions keep: springs,
// damping, actuation, ...); out-of-range slots are ignored.
void lsn_tally(long h, long slot, double amount) {
  if (slot >= 0 && slot < COUNTERS) robot(h).counts[static_cast<size_t>(slot)] += amount;
}

// The robot's counters into out (COUNTERS values); with reset != 0 they restart from 0.
void lsn_counts(long h, double* out, long reset) {
  Robot& rb = robot(h);
  for (size_t i = 0; i < COUNTERS; ++i) out[i] = rb.counts[i];
  if (reset != 0) rb.counts.fill(0.0);
}

// Seconds per call of bare ABA at (q, v, tau), over reps calls: the yardstick a compiled field
// evaluation is measured against (legsim bench robots). The fields compute the same forward
// dynamics more cheaply (forward_dynamics), so a field can cost less than this.
double lsn_time_aba(long h, const double* q, const double* v, const double* tau, long reps) {
  Robot& rb = robot(h);
  const long n = rb.model.nv;
  const ConstMap qm(q, n), vm(v, n), tm(tau, n);
  double sink = 0.0;
  const auto start = std::chrono::steady_clock::now();
  for (long i = 0; i < reps; ++i) sink += pinocchio::aba(rb.model, rb.data, qm, vm, tm)(0);
  const std::chrono::duration<double> elapsed = std::chrono::steady_clock::now() - start;
  return sink == sink ? elapsed.count() / static_cast<double>(reps) : elapsed.count();
}

}  // extern "C"
#pragma GCC visibility pop
