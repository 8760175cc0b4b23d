// The Cholesky factor of a robot's joint-space inertia M(q), for the few joints the bridge's
// robots have (2 to 20): plain loops over one buffer. Eigen's dynamic-size LLT and triangular
// solves dispatch on the size at every call (blocking, kernels for large matrices) and cost more
// than the arithmetic of a 7 x 7 matrix; the forward dynamics factors M at every field
// evaluation.
//
// Same contract as Eigen::LLT<Mat, Eigen::Upper>: M is read from its upper triangle, and
// compute() fails where a pivot is not positive (M not positive definite to rounding), or not a
// number.

#pragma once

#include <Eigen/Core>

#include <cmath>
#include <vector>

namespace legsim_small {

class SmallCholesky {
 public:
  using Mat = Eigen::MatrixXd;
  using Vec = Eigen::VectorXd;

  // Factor M = L L^T (L lower triangular, kept row-major in L_); false where M is not positive
  // definite (the factor is then unusable).
  bool compute(const Mat& M) {
    n_ = M.rows();
    L_.resize(static_cast<size_t>(n_ * n_));
    inverse_pivot_.resize(static_cast<size_t>(n_));
    ok_ = true;
    for (long j = 0; j < n_; ++j) {
      double* Lj = row(j);
      double pivot = M(j, j);
      for (long k = 0; k < j; ++k) pivot -= Lj[k] * Lj[k];
      if (!(pivot > 0.0)) {
        ok_ = false;
        return false;
      }
      const double d = std::sqrt(pivot);
      Lj[j] = d;
      inverse_pivot_[static_cast<size_t>(j)] = 1.0 / d;
      for (long i = j + 1; i < n_; ++i) {  // L(i, j) from M(j, i): the upper triangle
        double* Li = row(i);
        double value = M(j, i);
        for (long k = 0; k < j; ++k) value -= Li[k] * Lj[k];
        Li[j] = value * inverse_pivot_[static_cast<size_t>(j)];
      }
    }
    return true;
  }

  bool ok() const { return ok_; }

  // b := M^-1 b (b of the factored size).
  void solveInPlace(Vec& b) const { solve_column(b.data()); }

  // B := M^-1 B, column by column (B column-major, as Eigen's default).
  void solveInPlace(Mat& B) const {
    for (long c = 0; c < B.cols(); ++c) solve_column(B.data() + c * B.rows());
  }

 private:
  double* row(long i) { return L_.data() + i * n_; }
  const double* row(long i) const { return L_.data() + i * n_; }

  // y := L^-T L^-1 y (n entries at y).
  void solve_column(double* y) const {
    for (long i = 0; i < n_; ++i) {  // L z = y
      const double* Li = row(i);
      double value = y[i];
      for (long k = 0; k < i; ++k) value -= Li[k] * y[k];
      y[i] = value * inverse_pivot_[static_cast<size_t>(i)];
    }
    for (long i = n_ - 1; i >= 0; --i) {  // L^T x = z
      double value = y[i];
      for (long k = i + 1; k < n_; ++k) value -= row(k)[i] * y[k];
      y[i] = value * inverse_pivot_[static_cast<size_t>(i)];
    }
  }

  long n_ = 0;
  bool ok_ = false;
  std::vector<double> L_, inverse_pivot_;
};

}  // namespace legsim_small
