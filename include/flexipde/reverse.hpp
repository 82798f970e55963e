// Reverse-mode numbers on a tape: the gradient of one scalar output with respect to many inputs at
// the cost of a few evaluations, whatever the number of inputs.
//
// Forward-mode Duals (dual.hpp) carry one lane per input, so the derivatives with respect to several
// hundred inputs (the weights of a learned flux) would cost several hundred evaluations. A Rev
// instead records each operation with its local partial derivatives on a tape; one backward pass
// over the tape then gives d(output)/d(every input). The pointwise layer evaluates a model's rhs()
// at Rev numbers, with the parameter vectors' entries as the tape's inputs and the state and
// fields as constants, to form sum_i x_i^T dG_i/dtheta point by point (pointwise.hpp).
//
// A Rev is a value and a node index (-1: a constant, which records nothing). The tape is one per
// process: the sweeps that use it run one point at a time.
#pragma once
#include <algorithm>
#include <cmath>
#include <vector>

namespace flexipde {

class Tape {
public:
  // A node: up to two parents (-1: none) and the partial derivatives with respect to them. Indices
  // below inputs() are the inputs themselves, which take no node.
  struct Node {
    int a, b;
    double da, db;
  };
  // Starts a recording with `inputs` inputs (indices 0 .. inputs - 1).
  void begin(int inputs) {
    base_ = inputs, n_ = 0;
    if (adj_.size() < (size_t)inputs + 1) adj_.resize(inputs + 1024);
  }
  int inputs() const { return base_; }
  int push(int a, double da, int b, double db) {
    if (n_ == cap_) grow();
    nodes_[n_] = {a, b, da, db};
    return base_ + (int)n_++;
  }
  // Zero adjoints, seed outputs with seed(node, w), then backward(): d(sum of seeded outputs)/d(input e)
  // is adjoint(e) afterwards.
  void begin_seeding() { std::fill(adj_.begin(), adj_.begin() + base_ + n_, 0.0); }
  void seed(int node, double w) {
    if (node >= 0) adj_[node] += w;
  }
  void backward() {
    double *adj = adj_.data();
    for (size_t n = n_; n-- > 0;) {
      const double g = adj[base_ + n];
      if (g == 0) continue;
      const Node &nd = nodes_[n];
      if (nd.a >= 0) adj[nd.a] += nd.da * g;
      if (nd.b >= 0) adj[nd.b] += nd.db * g;
    }
  }
  double adjoint(int e) const { return adj_[e]; }

private:
  __attribute__((noinline)) void grow() {
    store_.resize(std::max<size_t>(1024, 2 * store_.size()));
    nodes_ = store_.data(), cap_ = store_.size();
    adj_.resize(base_ + cap_);
  }
  std::vector<Node> store_;
  Node *nodes_ = nullptr; // store_'s data and size, read on every push
  size_t n_ = 0, cap_ = 0;
  std::vector<double> adj_;
  int base_ = 0;
};

inline Tape process_tape; // a namespace-scope variable: no initialisation check on every operation
inline Tape &active_tape() { return process_tape; }

struct Rev {
  double v = 0;
  int i = -1;
  Rev() = default;
  Rev(double x) : v(x) {} // a constant
  Rev(double x, int node) : v(x), i(node) {}
  static Rev input(double x, int e) { return Rev(x, e); } // input e of the current recording
  Rev &operator+=(const Rev &b);
  Rev &operator-=(const Rev &b);
  Rev &operator*=(const Rev &b);
  Rev &operator/=(const Rev &b);
};

inline double value_of(const Rev &x) { return x.v; }

// r = f with partials da (w.r.t. a) and db (w.r.t. b); nothing is recorded when neither is on the tape.
inline Rev rev_node(double f, const Rev &a, double da, const Rev &b, double db) {
  if (a.i < 0 && b.i < 0) return Rev(f);
  return Rev(f, active_tape().push(a.i, da, b.i, db));
}
inline Rev rev_node(double f, const Rev &a, double da) {
  if (a.i < 0) return Rev(f);
  return Rev(f, active_tape().push(a.i, da, -1, 0));
}

inline Rev operator+(const Rev &a, const Rev &b) { return rev_node(a.v + b.v, a, 1.0, b, 1.0); }
inline Rev operator-(const Rev &a, const Rev &b) { return rev_node(a.v - b.v, a, 1.0, b, -1.0); }
inline Rev operator*(const Rev &a, const Rev &b) { return rev_node(a.v * b.v, a, b.v, b, a.v); }
inline Rev operator/(const Rev &a, const Rev &b) {
  const double inv = 1.0 / b.v, r = a.v * inv;
  return rev_node(r, a, inv, b, -r * inv);
}
inline Rev operator-(const Rev &a) { return rev_node(-a.v, a, -1.0); }
inline Rev &Rev::operator+=(const Rev &b) { return *this = *this + b; }
inline Rev &Rev::operator-=(const Rev &b) { return *this = *this - b; }
inline Rev &Rev::operator*=(const Rev &b) { return *this = *this * b; }
inline Rev &Rev::operator/=(const Rev &b) { return *this = *this / b; }

inline bool operator<(const Rev &a, const Rev &b) { return a.v < b.v; }
inline bool operator>(const Rev &a, const Rev &b) { return a.v > b.v; }

inline Rev sqrt(const Rev &a) {
  const double s = std::sqrt(a.v);
  return rev_node(s, a, 0.5 / s);
}
inline Rev exp(const Rev &a) {
  const double e = std::exp(a.v);
  return rev_node(e, a, e);
}
inline Rev log(const Rev &a) { return rev_node(std::log(a.v), a, 1.0 / a.v); }
inline Rev sin(const Rev &a) { return rev_node(std::sin(a.v), a, std::cos(a.v)); }
inline Rev cos(const Rev &a) { return rev_node(std::cos(a.v), a, -std::sin(a.v)); }
inline Rev tanh(const Rev &a) {
  const double t = std::tanh(a.v);
  return rev_node(t, a, 1.0 - t * t);
}
inline Rev abs(const Rev &a) { return a.v < 0 ? -a : a; }

} // namespace flexipde
