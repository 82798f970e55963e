// Forward-mode dual numbers: the derivatives of a model's pointwise equations, without writing them.
//
// Dual<T, N> carries a value v and N directional derivatives d[k]. Arithmetic follows the chain rule,
// so evaluating a function written generically in its number type at Duals seeded with unit vectors
// gives its Jacobian (N columns at a time), and at Duals seeded with a direction gives the product
// with that direction. T may itself be a Dual: Dual<Dual<double, 1>, N> carries second derivatives
// (Hessian-vector products), from the same function.
//
// Every operation is a fixed-size loop over N, fully inlined, so that for seeds known at compile time
// the compiler folds the zero lanes away and a derivative sweep costs what the hand-written one would.
#pragma once
#include <cmath>
#include <type_traits>

namespace flexipde {

// The plain-number functions stay visible next to the Dual overloads below.
using std::abs;
using std::cos;
using std::exp;
using std::log;
using std::sin;
using std::sqrt;
using std::tanh;

template <class T, int N>
struct Dual {
  T v{};
  T d[N]{};
  Dual() = default;
  Dual(double x) : v(x) {} // constants: no derivative
  template <class U, class = std::enable_if_t<!std::is_arithmetic<U>::value && std::is_constructible<T, U>::value>>
  Dual(const U &x) : v(x) {}
  static Dual seeded(const T &value, int k) {
    Dual r(value);
    r.d[k] = T(1.0);
    return r;
  }
  Dual &operator+=(const Dual &b) {
    v += b.v;
    for (int k = 0; k < N; ++k) d[k] += b.d[k];
    return *this;
  }
  Dual &operator-=(const Dual &b) {
    v -= b.v;
    for (int k = 0; k < N; ++k) d[k] -= b.d[k];
    return *this;
  }
  Dual &operator*=(const Dual &b) { return *this = *this * b; }
  Dual &operator/=(const Dual &b) { return *this = *this / b; }
};

template <class X> struct IsDual : std::false_type {};
template <class T, int N> struct IsDual<Dual<T, N>> : std::true_type {};

// The value of a number, whatever its type (a Dual's value, recursively).
inline double value_of(double x) { return x; }
template <class T, int N> double value_of(const Dual<T, N> &x) { return value_of(x.v); }

template <class T, int N> Dual<T, N> operator-(const Dual<T, N> &a) {
  Dual<T, N> r;
  r.v = -a.v;
  for (int k = 0; k < N; ++k) r.d[k] = -a.d[k];
  return r;
}
template <class T, int N> Dual<T, N> operator+(Dual<T, N> a, const Dual<T, N> &b) { return a += b; }
template <class T, int N> Dual<T, N> operator-(Dual<T, N> a, const Dual<T, N> &b) { return a -= b; }
template <class T, int N> Dual<T, N> operator*(const Dual<T, N> &a, const Dual<T, N> &b) {
  Dual<T, N> r;
  r.v = a.v * b.v;
  for (int k = 0; k < N; ++k) r.d[k] = a.d[k] * b.v + a.v * b.d[k];
  return r;
}
template <class T, int N> Dual<T, N> operator/(const Dual<T, N> &a, const Dual<T, N> &b) {
  Dual<T, N> r;
  const T inv = T(1.0) / b.v;
  r.v = a.v * inv;
  for (int k = 0; k < N; ++k) r.d[k] = (a.d[k] - r.v * b.d[k]) * inv;
  return r;
}
// Mixed with plain numbers (a double, or the Dual's own value type): no derivative lanes touched twice.
#define FLEXIPDE_DUAL_MIXED(S)                                                                                         \
  template <class T, int N> Dual<T, N> operator+(Dual<T, N> a, const S &b) {                                            \
    a.v += b;                                                                                                          \
    return a;                                                                                                          \
  }                                                                                                                    \
  template <class T, int N> Dual<T, N> operator+(const S &b, Dual<T, N> a) { return a + b; }                            \
  template <class T, int N> Dual<T, N> operator-(Dual<T, N> a, const S &b) {                                            \
    a.v -= b;                                                                                                          \
    return a;                                                                                                          \
  }                                                                                                                    \
  template <class T, int N> Dual<T, N> operator-(const S &b, const Dual<T, N> &a) { return -(a - b); }                  \
  template <class T, int N> Dual<T, N> operator*(Dual<T, N> a, const S &b) {                                            \
    a.v *= b;                                                                                                          \
    for (int k = 0; k < N; ++k) a.d[k] *= b;                                                                           \
    return a;                                                                                                          \
  }                                                                                                                    \
  template <class T, int N> Dual<T, N> operator*(const S &b, const Dual<T, N> &a) { return a * b; }                     \
  template <class T, int N> Dual<T, N> operator/(const Dual<T, N> &a, const S &b) { return a * (T(1.0) / b); }          \
  template <class T, int N> Dual<T, N> operator/(const S &b, const Dual<T, N> &a) { return Dual<T, N>(b) / a; }
FLEXIPDE_DUAL_MIXED(double)
#undef FLEXIPDE_DUAL_MIXED
// the value type itself (for nested Duals: Dual<Dual<double,1>,N> times a Dual<double,1>)
template <class T, int N, class = std::enable_if_t<IsDual<T>::value>> Dual<T, N> operator*(Dual<T, N> a, const T &b) {
  a.v *= b;
  for (int k = 0; k < N; ++k) a.d[k] *= b;
  return a;
}
template <class T, int N, class = std::enable_if_t<IsDual<T>::value>> Dual<T, N> operator*(const T &b, Dual<T, N> a) {
  return a * b;
}

template <class T, int N> bool operator<(const Dual<T, N> &a, const Dual<T, N> &b) { return value_of(a) < value_of(b); }
template <class T, int N> bool operator>(const Dual<T, N> &a, const Dual<T, N> &b) { return value_of(a) > value_of(b); }
template <class T, int N> bool operator<(const Dual<T, N> &a, double b) { return value_of(a) < b; }
template <class T, int N> bool operator>(const Dual<T, N> &a, double b) { return value_of(a) > b; }

// Elementary functions: f(a) with derivative lanes f'(a) a.d.
template <class T, int N, class F, class DF> Dual<T, N> chain(const Dual<T, N> &a, F f, DF df) {
  Dual<T, N> r;
  r.v = f(a.v);
  const T s = df(a.v);
  for (int k = 0; k < N; ++k) r.d[k] = s * a.d[k];
  return r;
}
template <class T, int N> Dual<T, N> sqrt(const Dual<T, N> &a) {
  using std::sqrt;
  const T s = sqrt(a.v);
  return chain(a, [&](const T &) { return s; }, [&](const T &) { return T(0.5) / s; });
}
template <class T, int N> Dual<T, N> exp(const Dual<T, N> &a) {
  using std::exp;
  const T e = exp(a.v);
  return chain(a, [&](const T &) { return e; }, [&](const T &) { return e; });
}
template <class T, int N> Dual<T, N> log(const Dual<T, N> &a) {
  using std::log;
  return chain(a, [](const T &x) { return log(x); }, [](const T &x) { return T(1.0) / x; });
}
template <class T, int N> Dual<T, N> sin(const Dual<T, N> &a) {
  using std::cos;
  using std::sin;
  return chain(a, [](const T &x) { return sin(x); }, [](const T &x) { return cos(x); });
}
template <class T, int N> Dual<T, N> cos(const Dual<T, N> &a) {
  using std::cos;
  using std::sin;
  return chain(a, [](const T &x) { return cos(x); }, [](const T &x) { return -sin(x); });
}
template <class T, int N> Dual<T, N> tanh(const Dual<T, N> &a) {
  using std::tanh;
  const T t = tanh(a.v);
  return chain(a, [&](const T &) { return t; }, [&](const T &) { return T(1.0) - t * t; });
}
// x if pick, else y, lane by lane: a choice between plain numbers in every lane, which the compiler
// makes without a branch (a branch choosing a whole Dual kept the loops over points from vectorising).
template <class X> X if_else(bool pick, const X &x, const X &y) { return pick ? x : y; }
template <class T, int N> Dual<T, N> if_else(bool pick, const Dual<T, N> &x, const Dual<T, N> &y) {
  Dual<T, N> r;
  r.v = if_else(pick, x.v, y.v);
  for (int k = 0; k < N; ++k) r.d[k] = if_else(pick, x.d[k], y.d[k]);
  return r;
}
// |a| and max/min: differentiable almost everywhere; at a tie the first argument's lanes are taken.
template <class T, int N> Dual<T, N> abs(const Dual<T, N> &a) { return if_else(value_of(a) < 0, -a, a); }
template <class X> X max(const X &a, const X &b) { return if_else(value_of(b) > value_of(a), b, a); }
template <class X> X min(const X &a, const X &b) { return if_else(value_of(b) < value_of(a), b, a); }

// x^2, the commonest power, without a call.
template <class X> X sqr(const X &x) { return x * x; }

} // namespace flexipde
