// Pinocchio's rigid-body algorithms behind a plain C ABI, for the numba-compiled twins of the
// robots' modes (legsim.robots.bridge.twins). Every function takes a model handle and raw
// float64 pointers; numba calls them by symbol name (numba.types.ExternalFunction), so a
// compiled kernel that calls them caches on disk like any other.
//
// The algorithms are those the Python bridge calls through Pinocchio's Python bindings
// (robots/bridge/dynamics.py and impacts.py), in the same order, so both paths agree to
// rounding: ABA with applied forces; the KKT contact dynamics through the Schur complement of
// ABA (a0 = aba(q, v, tau), lambda = (J M^-1 J^T)^-1 (-(J a0 + dJ/dt v)), a = a0 + M^-1 J^T lambda);
// the generalised Newton impact; frame positions and velocities in the world's axes.
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

#include <chrono>
#include <memory>
#include <mutex>
#include <vector>

namespace {

// The joints the bridge admits (nq == nv: bounded revolute and prismatic joints along the
// axes). A collection of these six alone, rather than Pinocchio's default of 25 kinds, keeps
// every algorithm's joint dispatch small: the library compiles in a fraction of the time and
// runs the same arithmetic.
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

constexpr int kVersion = 2;

// Joint type codes of the model description (see lsn_create).
enum JointCode { RX = 0, RY = 1, RZ = 2, PX = 3, PY = 4, PZ = 5 };

// A constraint row block: a joint stop (one row selecting a signed dof) or a point contact
// (rows x and z of the frame's world-aligned Jacobian, or z only); the normal row is the last.
struct Rigid {
  int kind;  // 0 stop, 1 point
  int id;    // stop: velocity index; point: frame id
  double sign;
  int rows;
};

struct Robot {
  Model model;
  Data data;
  explicit Robot(Model m) : model(std::move(m)), data(model) {}
};

std::vector<std::unique_ptr<Robot>> robots;
std::mutex robots_mutex;

Robot& robot(long h) { return *robots[static_cast<size_t>(h)]; }

pinocchio::SE3 read_placement(const double* d) {
  Eigen::Matrix3d R;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) R(i, j) = d[3 * i + j];
  return pinocchio::SE3(R, Eigen::Vector3d(d[9], d[10], d[11]));
}

bool add_joint(Model& model, int code, int parent, const pinocchio::SE3& placement, int index) {
  const std::string name = "j" + std::to_string(index);
  switch (code) {
    case RX: model.addJoint(parent, PlanarJointsTpl<double, 0>::JointModelRX(), placement, name); return true;
    case RY: model.addJoint(parent, PlanarJointsTpl<double, 0>::JointModelRY(), placement, name); return true;
    case RZ: model.addJoint(parent, PlanarJointsTpl<double, 0>::JointModelRZ(), placement, name); return true;
    case PX: model.addJoint(parent, PlanarJointsTpl<double, 0>::JointModelPX(), placement, name); return true;
    case PY: model.addJoint(parent, PlanarJointsTpl<double, 0>::JointModelPY(), placement, name); return true;
    case PZ: model.addJoint(parent, PlanarJointsTpl<double, 0>::JointModelPZ(), placement, name); return true;
    default: return false;
  }
}

std::vector<Rigid> read_rigid(long n, const double* desc) {
  std::vector<Rigid> out(static_cast<size_t>(n));
  for (long i = 0; i < n; ++i)
    out[i] = Rigid{static_cast<int>(desc[4 * i]), static_cast<int>(desc[4 * i + 1]), desc[4 * i + 2],
                   static_cast<int>(desc[4 * i + 3])};
  return out;
}

int total_rows(const std::vector<Rigid>& rigid) {
  int rows = 0;
  for (const Rigid& r : rigid) rows += r.rows;
  return rows;
}

// The stacked constraint Jacobian (rows, nv); with drift also dJ/dt v (the classical
// acceleration of each point at zero joint acceleration). Kinematics at (q, v, 0) first.
void constraint_rows(Robot& rb, const ConstMap& q, const ConstMap& v, const std::vector<Rigid>& rigid, bool drift,
                     Mat& J, Vec& gamma) {
  const Model& model = rb.model;
  Data& data = rb.data;
  const int rows = total_rows(rigid);
  J.setZero(rows, model.nv);
  gamma.setZero(rows);
  bool points = false;
  for (const Rigid& r : rigid) points = points || r.kind == 1;
  if (points) {
    pinocchio::forwardKinematics(model, data, q, v, Vec::Zero(model.nv));
    pinocchio::computeJointJacobians(model, data, q);
  }
  Mat Jf(6, model.nv);
  int i = 0;
  for (const Rigid& r : rigid) {
    if (r.kind == 0) {
      J(i, r.id) = r.sign;
    } else {
      Jf.setZero();
      pinocchio::getFrameJacobian(model, data, static_cast<pinocchio::FrameIndex>(r.id), pinocchio::LOCAL_WORLD_ALIGNED,
                                  Jf);
      if (r.rows == 2) {
        J.row(i) = Jf.row(0);
        J.row(i + 1) = Jf.row(2);
      } else {
        J.row(i) = Jf.row(2);
      }
      if (drift) {
        const Eigen::Vector3d acc = pinocchio::getFrameClassicalAcceleration(
                             model, data, static_cast<pinocchio::FrameIndex>(r.id), pinocchio::LOCAL_WORLD_ALIGNED)
                             .linear();
        if (r.rows == 2) {
          gamma(i) = acc(0);
          gamma(i + 1) = acc(2);
        } else {
          gamma(i) = acc(2);
        }
      }
    }
    i += r.rows;
  }
}

// M^-1 as a full symmetric matrix (Pinocchio fills its upper triangle).
Mat minverse(Robot& rb, const ConstMap& q) {
  pinocchio::computeMinverse(rb.model, rb.data, q);
  Mat Minv = rb.data.Minv;
  Minv.triangularView<Eigen::StrictlyLower>() = Minv.transpose().triangularView<Eigen::StrictlyLower>();
  return Minv;
}

// Solve A y = b for the small SPD Delassus matrix; one and two rows in closed form as
// robots/bridge/dynamics.solve_small does.
Vec solve_small(const Mat& A, const Vec& b) {
  if (A.rows() == 1) return Vec::Constant(1, b(0) / A(0, 0));
  if (A.rows() == 2) {
    const double det = A(0, 0) * A(1, 1) - A(0, 1) * A(1, 0);
    Vec y(2);
    y(0) = (A(1, 1) * b(0) - A(0, 1) * b(1)) / det;
    y(1) = (A(0, 0) * b(1) - A(1, 0) * b(0)) / det;
    return y;
  }
  return A.partialPivLu().solve(b);
}

}  // namespace

extern "C" {

// Version of this C interface (bumped when a signature changes).
long lsn_version() { return kVersion; }

// Build a model from a flat description and return its handle (>= 0), or -1 on a bad
// description. Layout: [njoints-1, then per joint (code, parent, placement[12],
// mass, lever[3], inertia about the centre of mass[9]), nframes-1, then per frame
// (parent joint, placement[12]), gravity linear[3]]. A placement is R row-major then p.
// Frames are added in order after the universe frame, so frame ids are the Python model's.
long lsn_create(const double* desc, long size) {
  Model model;
  long k = 0;
  auto need = [&](long n) { return k + n <= size; };
  if (!need(1)) return -1;
  const long joints = static_cast<long>(desc[k++]);
  for (long j = 0; j < joints; ++j) {
    if (!need(28)) return -1;
    const int code = static_cast<int>(desc[k]);
    const int parent = static_cast<int>(desc[k + 1]);
    const pinocchio::SE3 placement = read_placement(desc + k + 2);
    const double mass = desc[k + 14];
    const Eigen::Vector3d lever(desc[k + 15], desc[k + 16], desc[k + 17]);
    Eigen::Matrix3d I;
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) I(a, b) = desc[k + 18 + 3 * a + b];
    k += 27;
    if (parent < 0 || parent > j || !add_joint(model, code, parent, placement, static_cast<int>(j + 1))) return -1;
    model.appendBodyToJoint(static_cast<pinocchio::JointIndex>(j + 1), pinocchio::Inertia(mass, lever, I),
                            pinocchio::SE3::Identity());
  }
  if (!need(1)) return -1;
  const long frames = static_cast<long>(desc[k++]);
  // Joints added their own frames; replace the list by the Python model's (universe kept).
  model.frames.resize(1);
  model.nframes = 1;
  for (long f = 0; f < frames; ++f) {
    if (!need(13)) return -1;
    const int parent = static_cast<int>(desc[k]);
    if (parent < 0 || parent >= model.njoints) return -1;
    model.addFrame(Model::Frame("f" + std::to_string(f + 1), static_cast<pinocchio::JointIndex>(parent), 0,
                                    read_placement(desc + k + 1), pinocchio::OP_FRAME),
                   false);
    k += 13;
  }
  if (!need(3)) return -1;
  model.gravity.linear(Eigen::Vector3d(desc[k], desc[k + 1], desc[k + 2]));
  model.gravity.angular(Eigen::Vector3d::Zero());
  std::lock_guard<std::mutex> lock(robots_mutex);
  robots.push_back(std::make_unique<Robot>(std::move(model)));
  return static_cast<long>(robots.size() - 1);
}

long lsn_nv(long h) { return robot(h).model.nv; }

// a = ABA(q, v, tau): the unconstrained joint acceleration under applied forces tau.
void lsn_aba(long h, const double* q, const double* v, const double* tau, double* a) {
  Robot& rb = robot(h);
  const long n = rb.model.nv;
  OutMap(a, n) = pinocchio::aba(rb.model, rb.data, ConstMap(q, n), ConstMap(v, n), ConstMap(tau, n));
}

// Positions and world-aligned linear velocities of frames: out[4 i .. 4 i + 3] = (x, z, vx, vz)
// of frames[i], from one kinematics pass at (q, v).
void lsn_frames(long h, const double* q, const double* v, long count, const double* frames, double* out) {
  Robot& rb = robot(h);
  const long n = rb.model.nv;
  pinocchio::forwardKinematics(rb.model, rb.data, ConstMap(q, n), ConstMap(v, n));
  for (long i = 0; i < count; ++i) {
    const auto id = static_cast<pinocchio::FrameIndex>(frames[i]);
    const Eigen::Vector3d p = pinocchio::updateFramePlacement(rb.model, rb.data, id).translation();
    const Eigen::Vector3d w = pinocchio::getFrameVelocity(rb.model, rb.data, id, pinocchio::LOCAL_WORLD_ALIGNED).linear();
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
  Mat Jf = Mat::Zero(6, n);
  pinocchio::computeFrameJacobian(rb.model, rb.data, ConstMap(q, n), id, pinocchio::LOCAL_WORLD_ALIGNED, Jf);
  const Eigen::Vector3d p = rb.data.oMf[id].translation();
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

// The generalised gravity g(q) (nv): the joint forces that hold the robot still against gravity.
void lsn_gravity(long h, const double* q, double* out) {
  Robot& rb = robot(h);
  const long n = rb.model.nv;
  OutMap(out, n) = pinocchio::computeGeneralizedGravity(rb.model, rb.data, ConstMap(q, n));
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
// forces lam (rows), the normal force of each block last and >= 0 when it pushes.
void lsn_constrained(long h, const double* q, const double* v, const double* tau, long count, const double* rigid,
                     double* a, double* lam) {
  Robot& rb = robot(h);
  const long n = rb.model.nv;
  const ConstMap qm(q, n), vm(v, n);
  Vec acc = pinocchio::aba(rb.model, rb.data, qm, vm, ConstMap(tau, n));
  const std::vector<Rigid> blocks = read_rigid(count, rigid);
  const Mat Minv = minverse(rb, qm);
  Mat J;
  Vec gamma;
  constraint_rows(rb, qm, vm, blocks, true, J, gamma);
  const Mat MJt = Minv * J.transpose();
  const Vec l = solve_small(J * MJt, -(J * acc + gamma));
  acc += MJt * l;
  OutMap(a, n) = acc;
  OutMap(lam, l.size()) = l;
}

// The generalised Newton impact: v+ = v + M^-1 J^T (J M^-1 J^T)^-1 (-(1 + c) J v), with the
// restitution c of each block (coeff, one per block) on its rows.
void lsn_impact(long h, const double* q, const double* v, long count, const double* rigid, const double* coeff,
                double* v_out) {
  Robot& rb = robot(h);
  const long n = rb.model.nv;
  const ConstMap qm(q, n), vm(v, n);
  const std::vector<Rigid> blocks = read_rigid(count, rigid);
  Mat J;
  Vec gamma;
  constraint_rows(rb, qm, vm, blocks, false, J, gamma);
  Vec c(J.rows());
  int i = 0;
  for (long b = 0; b < count; ++b)
    for (int r = 0; r < blocks[b].rows; ++r) c(i++) = coeff[b];
  const Mat Minv = minverse(rb, qm);
  const Mat MJt = Minv * J.transpose();
  const Vec Jv = J * vm;
  const Vec rhs = -((Vec::Ones(c.size()) + c).cwiseProduct(Jv));
  OutMap(v_out, n) = vm + MJt * solve_small(J * MJt, rhs);
}

// Seconds per call of bare ABA at (q, v, tau), over reps calls: the cost floor a compiled field
// evaluation is measured against (legsim bench robots).
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
