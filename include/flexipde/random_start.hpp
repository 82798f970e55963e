// A smooth random periodic start for Burgers-type models, the same function of x in every model and
// on every grid (so a coarse and a fine model can start from one function):
//
//   u0(x) = A s(x) / max|s| + B,   s(x) = sum_{k=1}^{K} (c_k / k) sin(2 pi k x / L + phi_k),
//
// c_k uniform in [-1, 1] and phi_k uniform in [0, 2 pi), drawn from std::mt19937 seeded with `seed`
// (its raw outputs, which the standard fixes: the same numbers on every platform). max|s| is taken
// over 4096 samples. cell_average(x, w) is the exact mean of u0 over [x - w/2, x + w/2].
#pragma once
#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

namespace flexipde {

class RandomStart {
public:
  void make(unsigned seed, int modes, double amplitude, double offset, double length) {
    std::mt19937 gen(seed);
    auto uniform = [&] { return (double)gen() / 4294967296.0; };
    c_.assign(modes, 0.0), phi_.assign(modes, 0.0);
    for (int k = 0; k < modes; ++k) c_[k] = (2 * uniform() - 1) / (k + 1), phi_[k] = 2 * M_PI * uniform();
    length_ = length, amplitude_ = amplitude, offset_ = offset, scale_ = 1;
    double m = 0;
    for (int i = 0; i < 4096; ++i) m = std::max(m, std::fabs(shape(length * i / 4096.0, 0)));
    scale_ = m > 0 ? 1 / m : 1;
  }
  double operator()(double x) const { return amplitude_ * scale_ * shape(x, 0) + offset_; }
  double cell_average(double x, double w) const { return amplitude_ * scale_ * shape(x, w) + offset_; }

private:
  // s(x), or its mean over a cell of width w (each sine times sin(a w / 2) / (a w / 2)).
  double shape(double x, double w) const {
    double s = 0;
    for (size_t k = 0; k < c_.size(); ++k) {
      const double a = 2 * M_PI * (k + 1) / length_;
      const double damp = w > 0 ? std::sin(a * w / 2) / (a * w / 2) : 1.0;
      s += c_[k] * damp * std::sin(a * x + phi_[k]);
    }
    return s;
  }
  std::vector<double> c_, phi_;
  double length_ = 1, amplitude_ = 1, offset_ = 0, scale_ = 1;
};

} // namespace flexipde
