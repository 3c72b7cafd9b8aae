// The Python module pwcontact._pwcontact (pybind11): numpy arrays in, numpy
// arrays out, the GIL released during every computation. The package
// (python/pwcontact/__init__.py) wraps it with the Box convention, GSD
// reading through python3-gsd and the docstrings users see.
//
// Arrays are read in place, whatever their strides (PairBatchView's strides:
// rows of C-ordered arrays by gathers, columns of Fortran-ordered ones by
// plain loads, a row broadcast against many with stride 0), and converted
// only when their dtype is not the one computed in (numpy makes that copy).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <functional>
#include <map>

#include <omp.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <mutex>
#include <shared_mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "fixtures/families.hpp"
#include "number_text.hpp"
#include "parallel_errors.hpp"
#include "pwcontact/pwcontact.hpp"
#include "thread_count.hpp"
#if PWCONTACT_WITH_MPI
#include "mpi/agree.hpp"
#include "pwcontact/mpi.hpp"
#endif

namespace py = pybind11;
using pwcontact::Status;

namespace {

// A 2-D view (rows of k numbers) of an array of shape (N, k) or (k,), by
// element strides; rows == 1 and row_stride == 0 for (k,).
template <class T>
struct Rows {
  py::array_t<T> keep;  // holds the data (a converted copy, or the caller's array)
  const T* data = nullptr;
  std::size_t rows = 0;
  std::ptrdiff_t row_stride = 0, column_stride = 1;
  bool broadcast = false;
  T at(std::size_t i, int k) const {
    return data[std::ptrdiff_t(broadcast ? 0 : i) * row_stride + k * column_stride];
  }
};

std::string shape_text(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t d = 0; d < a.ndim(); ++d) s += (d ? ", " : "") + std::to_string(a.shape(d));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

template <class T>
Rows<T> rows_of(const py::handle& object, int k, const char* name) {
  // Complex numbers, strings, dates: not numbers a cast may take (a complex
  // one would lose its imaginary part, a string be parsed).
  if (py::isinstance<py::array>(object)) {
    const char kind = py::reinterpret_borrow<py::array>(object).dtype().kind();
    if (kind != 'f' && kind != 'i' && kind != 'u' && kind != 'b' && kind != 'O')
      throw py::value_error(
          std::string(name) + " must be an array of real numbers, got dtype " +
          std::string(py::str(py::reinterpret_borrow<py::array>(object).dtype())));
  }
  auto a = py::array_t<T, py::array::forcecast>::ensure(object);
  if (!a) throw py::value_error(std::string(name) + " must be an array of numbers");
  // Strides the batch calls cannot read in place (not whole numbers, or
  // beyond their gathers' +-2^26 numbers): a C-ordered copy.
  constexpr py::ssize_t reach = py::ssize_t(1) << 26;
  for (py::ssize_t d = 0; d < a.ndim(); ++d)
    if (a.strides(d) % py::ssize_t(sizeof(T)) != 0 ||
        a.strides(d) / py::ssize_t(sizeof(T)) > reach ||
        a.strides(d) / py::ssize_t(sizeof(T)) < -reach) {
      a = py::array_t<T, py::array::c_style | py::array::forcecast>::ensure(a);
      break;
    }
  Rows<T> r;
  if (a.ndim() == 1 && a.shape(0) == k) {
    r.rows = 1;
    r.broadcast = true;
    r.column_stride = a.strides(0) / py::ssize_t(sizeof(T));
  } else if (a.ndim() == 2 && a.shape(1) == k) {
    r.rows = std::size_t(a.shape(0));
    r.row_stride = a.strides(0) / py::ssize_t(sizeof(T));
    r.column_stride = a.strides(1) / py::ssize_t(sizeof(T));
  } else {
    throw py::value_error(std::string(name) + " must have shape (N, " + std::to_string(k) +
                          ") or (" + std::to_string(k) + ",), got " + shape_text(a));
  }
  r.data = a.data();
  r.keep = std::move(a);
  return r;
}

// Quaternions (N, 4) or (4,), or the identity for all when none are given.
Rows<double> orientation_rows(const py::object& orientations) {
  static const double identity[4] = {1, 0, 0, 0};
  if (!orientations.is_none()) return rows_of<double>(orientations, 4, "orientations");
  Rows<double> r;
  r.data = identity;
  r.rows = 1;
  r.broadcast = true;
  return r;
}

// Throws unless `a` is broadcast or has n rows, as the positions have.
template <class T>
void expect_rows(const Rows<T>& a, std::size_t n, const char* name) {
  if (!a.broadcast && a.rows != n)
    throw py::value_error(std::string(name) + " has " + std::to_string(a.rows) +
                          " rows, positions " + std::to_string(n));
}

// The common N of arrays of N rows or broadcast ones (N = 1 when all are).
std::size_t common_rows(std::initializer_list<std::pair<std::size_t, bool>> arrays,
                        std::initializer_list<const char*> names) {
  std::size_t n = 1;
  bool any = false;
  for (const auto& [rows, broadcast] : arrays)
    if (!broadcast) {
      if (any && rows != n) {
        std::string text = "arrays of different lengths:";
        auto name = names.begin();
        for (const auto& [r, b] : arrays)
          text += std::string(" ") + *name++ + (b ? " (broadcast)" : " " + std::to_string(r));
        throw py::value_error(text);
      }
      n = rows;
      any = true;
    }
  return n;
}

int thread_count(int threads) {
  // (At most the command line's 1024: 10^5 threads segfaulted the
  // interpreter in the batched MovingScene query and in screen.)
  if (threads < 0 || threads > pwcontact::detail::max_threads)
    throw py::value_error("threads must be in 0 .. 1024 (0: all), got " + std::to_string(threads));
  return threads > 0 ? threads : omp_get_max_threads();
}

pwcontact::BatchOptions batch_options(const std::string& precision, const py::object& iterations,
                                      const std::string& accuracy, const std::string& isa) {
  pwcontact::BatchOptions o;
  const auto p = pwcontact::parse_precision(precision);
  if (!p)
    throw py::value_error("precision must be one of auto, double, float, mixed; got '" + precision +
                          "'");
  o.precision = *p;
  const auto a = pwcontact::parse_accuracy(accuracy);
  if (!a) throw py::value_error("accuracy must be standard or high; got '" + accuracy + "'");
  o.accuracy = *a;
  const auto i = pwcontact::parse_isa(isa);
  if (!i)
    throw py::value_error("isa must be one of auto, sse2, avx2, avx512, fallback; got '" + isa +
                          "'");
  o.isa = *i;
  if (iterations.is_none() ||
      (py::isinstance<py::str>(iterations) && iterations.cast<std::string>() == "auto")) {
    o.iterations = pwcontact::automatic_iterations;
  } else {
    // (0 is automatic, as in BatchOptions and on the command line.)
    const long n = iterations.cast<long>();
    if (n < 0 || n > pwcontact::max_fixed_iterations)
      throw py::value_error("iterations must be 'auto' or an integer 0 .. " +
                            std::to_string(pwcontact::max_fixed_iterations) + " (0: auto), got " +
                            std::to_string(n));
    o.iterations = int(n);
  }
  return o;
}

struct Outputs {
  bool mu2 = true, lambda = false, contact_point = false, normal = false, gradient = false;
};

Outputs parse_outputs(const std::vector<std::string>& names) {
  Outputs o;
  o.mu2 = false;
  for (const std::string& n : names) {
    if (n == "mu2")
      o.mu2 = true;
    else if (n == "lambda")
      o.lambda = true;
    else if (n == "contact_point")
      o.contact_point = true;
    else if (n == "normal")
      o.normal = true;
    else if (n == "gradient")
      o.gradient = true;
    else
      throw py::value_error("unknown output '" + n +
                            "' (outputs: mu2, lambda, contact_point, normal, gradient)");
  }
  return o;
}

// An output array of n elements: the caller's (out[key], which must be a
// writeable C-contiguous array of shape (n,) and of the result's dtype), or
// a new one.
template <class T>
py::array_t<T> output_array(const py::object& out, const char* key, std::size_t n) {
  if (out.is_none() || !py::cast<py::dict>(out).contains(key))
    return py::array_t<T>(py::ssize_t(n));
  const py::object given = py::cast<py::dict>(out)[key];
  const std::string what = std::string("out['") + key + "']";
  if (!py::isinstance<py::array>(given)) throw py::value_error(what + " must be a numpy array");
  const py::array a = py::reinterpret_borrow<py::array>(given);
  if (!a.dtype().equal(py::dtype::of<T>()))  // (a dtype with metadata is equal, not the same)
    throw py::value_error(what + " must have dtype " + std::string(py::str(py::dtype::of<T>())) +
                          ", got " + std::string(py::str(a.dtype())));
  if (a.ndim() != 1 || std::size_t(a.shape(0)) != n)
    throw py::value_error(what + " must have shape (" + std::to_string(n) + ",), got " +
                          shape_text(a));
  if (!(a.flags() & py::array::c_style) || !a.writeable())
    throw py::value_error(what + " must be C-contiguous and writeable");
  return py::reinterpret_borrow<py::array_t<T>>(given);
}

// The pairs where the caller's arrays hold them: component k of pair i at
// data + i * row_stride + k * column_stride (row_stride 0 for a row
// broadcast against every pair).
template <class T>
pwcontact::PairBatchView<T> view_of(const Rows<T>& r12, const Rows<T>& q1, const Rows<T>& q2,
                                    std::size_t n) {
  pwcontact::PairBatchView<T> view;
  view.size = n;
  for (int k = 0; k < 3; ++k) view.r12[k] = r12.data + k * r12.column_stride;
  for (int k = 0; k < 6; ++k) {
    view.q1[k] = q1.data + k * q1.column_stride;
    view.q2[k] = q2.data + k * q2.column_stride;
  }
  view.r12_stride = r12.broadcast ? 0 : r12.row_stride;
  view.q1_stride = q1.broadcast ? 0 : q1.row_stride;
  view.q2_stride = q2.broadcast ? 0 : q2.row_stride;
  return view;
}

// solve() with the GIL released, a C++ exception kept for the caller's thread.
template <class Solve>
void without_gil(Solve&& solve) {
  pwcontact::detail::ParallelErrors errors;
  {
    py::gil_scoped_release release;
    errors.run(solve);
  }
  errors.rethrow_if_failed();
}

py::dict report_dict(const pwcontact::BatchReport& t) {
  py::dict d;
  d["pairs"] = t.pairs;
  d["fallbacks"] = t.fallbacks;
  d["finished_in_double"] = t.finished_in_double;
  d["invalid"] = t.invalid;
  d["mean_evaluations"] = t.mean_evaluations;
  d["isa"] = pwcontact::isa_name(t.isa);
  d["precision"] = pwcontact::precision_name(t.precision);
  return d;
}

// One column-major (3, n) block returned as its (n, 3) transpose (no copy).
template <class T>
py::array_t<T> vectors(std::size_t n) {
  return py::array_t<T>({py::ssize_t(3), py::ssize_t(n)});
}

template <class T>
py::dict contact_function_typed(const py::handle& r12_in, const py::handle& q1_in,
                                const py::handle& q2_in, const Outputs& wanted,
                                pwcontact::BatchOptions options, int threads,
                                const py::object& lambda_start_in, const py::object& out_in) {
  const Rows<T> r12 = rows_of<T>(r12_in, 3, "r12"), q1 = rows_of<T>(q1_in, 6, "q1"),
                q2 = rows_of<T>(q2_in, 6, "q2");
  const std::size_t n =
      common_rows({{r12.rows, r12.broadcast}, {q1.rows, q1.broadcast}, {q2.rows, q2.broadcast}},
                  {"r12", "q1", "q2"});
  py::array_t<T> lambda_start;  // (a default array_t is an empty array, not a null one)
  const bool warm = !lambda_start_in.is_none();
  if (warm) {
    // (ensure() of what numpy cannot convert is a null array, which the
    // assignment refuses with pybind11's own message: taken apart here.)
    auto converted =
        py::array_t<T, py::array::c_style | py::array::forcecast>::ensure(lambda_start_in);
    if (!converted) {
      PyErr_Clear();
      throw py::value_error("lambda_start must be an array of numbers of shape (" +
                            std::to_string(n) + ",)");
    }
    lambda_start = std::move(converted);
    if (lambda_start.ndim() != 1 || std::size_t(lambda_start.shape(0)) != n)
      throw py::value_error("lambda_start must have shape (" + std::to_string(n) + ",)");
  }
  // mu2 is always computed (the kernels' answer); lambda and the vectors
  // only when asked for. mu2, lambda and status go into the caller's arrays
  // where `out` gives them (reused across calls: no fresh pages to fault in).
  py::array_t<T> mu2 = output_array<T>(out_in, "mu2", n), lambda;
  py::array_t<std::uint8_t> status = output_array<std::uint8_t>(out_in, "status", n);
  py::array_t<T> point, normal, gradient;
  if (wanted.lambda) lambda = output_array<T>(out_in, "lambda", n);
  if (wanted.contact_point) point = vectors<T>(n);
  if (wanted.normal) normal = vectors<T>(n);
  if (wanted.gradient) gradient = vectors<T>(n);
  pwcontact::PairBatchView<T> view = view_of(r12, q1, q2, n);
  view.lambda_start = warm ? lambda_start.data() : nullptr;
  pwcontact::ContactOutputs<T> outputs;
  outputs.mu2 = mu2.mutable_data();
  outputs.lambda = wanted.lambda ? lambda.mutable_data() : nullptr;
  outputs.status = reinterpret_cast<Status*>(status.mutable_data());
  for (int k = 0; k < 3; ++k) {
    if (wanted.contact_point) outputs.contact_point[k] = point.mutable_data() + k * n;
    if (wanted.normal) outputs.normal[k] = normal.mutable_data() + k * n;
    if (wanted.gradient) outputs.gradient[k] = gradient.mutable_data() + k * n;
  }
  options.threads = thread_count(threads);
  pwcontact::BatchReport totals;
  without_gil([&] { totals = pwcontact::contact_function_batch(view, outputs, options); });
  py::dict result;
  if (wanted.mu2) result["mu2"] = mu2;
  if (wanted.lambda) result["lambda"] = lambda;
  result["status"] = status;
  if (wanted.contact_point) result["contact_point"] = point.attr("T");
  if (wanted.normal) result["normal"] = normal.attr("T");
  if (wanted.gradient) result["gradient"] = gradient.attr("T");
  result["report"] = report_dict(totals);
  return result;
}

// Any float32 array: of either byte order, or with metadata (rows_of reads
// it as native float32).
bool is_float32(const py::handle& object) {
  if (!py::isinstance<py::array>(object)) return false;
  const py::dtype d = py::reinterpret_borrow<py::array>(object).dtype();
  return d.kind() == 'f' && d.itemsize() == 4;
}

py::dict contact_function(const py::object& r12, const py::object& q1, const py::object& q2,
                          const std::vector<std::string>& outputs, const std::string& precision,
                          const py::object& iterations, const std::string& accuracy, int threads,
                          const std::string& isa, const py::object& lambda_start,
                          const py::object& out) {
  const Outputs wanted = parse_outputs(outputs);
  const pwcontact::BatchOptions options = batch_options(precision, iterations, accuracy, isa);
  // float32 pairs are solved as float pairs (float results) unless a
  // precision other than float is asked for; anything else in double.
  const bool single = is_float32(r12) && is_float32(q1) && is_float32(q2) &&
                      (options.precision == pwcontact::Precision::automatic ||
                       options.precision == pwcontact::Precision::single_precision);
  if (single)
    return contact_function_typed<float>(r12, q1, q2, wanted, options, threads, lambda_start, out);
  return contact_function_typed<double>(r12, q1, q2, wanted, options, threads, lambda_start, out);
}

template <class T>
py::dict overlap_typed(const py::handle& r12_in, const py::handle& q1_in, const py::handle& q2_in,
                       double cutoff, pwcontact::BatchOptions options, int threads) {
  const Rows<T> r12 = rows_of<T>(r12_in, 3, "r12"), q1 = rows_of<T>(q1_in, 6, "q1"),
                q2 = rows_of<T>(q2_in, 6, "q2");
  const std::size_t n =
      common_rows({{r12.rows, r12.broadcast}, {q1.rows, q1.broadcast}, {q2.rows, q2.broadcast}},
                  {"r12", "q1", "q2"});
  py::array_t<bool> overlap{py::ssize_t(n)};
  py::array_t<std::uint8_t> status{py::ssize_t(n)};
  const pwcontact::OverlapOutputs outputs{reinterpret_cast<std::uint8_t*>(overlap.mutable_data()),
                                          reinterpret_cast<Status*>(status.mutable_data())};
  options.threads = thread_count(threads);
  pwcontact::BatchReport totals;
  without_gil([&] {
    totals = pwcontact::overlap_batch(view_of(r12, q1, q2, n), outputs, options, cutoff);
  });
  py::dict result;
  result["overlap"] = overlap;
  result["status"] = status;
  py::dict report = report_dict(totals);
  report["decided_by_prefilter"] = totals.decided_by_prefilter;
  report["decided_by_certificate"] = totals.decided_by_certificate;
  report["overlapping"] = totals.overlapping;
  result["report"] = report;
  return result;
}

py::dict overlap(const py::object& r12, const py::object& q1, const py::object& q2, double cutoff,
                 const std::string& precision, const py::object& iterations, int threads,
                 const std::string& isa) {
  if (!(cutoff > 0) || !std::isfinite(cutoff))
    throw py::value_error("cutoff must be positive and finite, got " +
                          pwcontact::detail::number_text(cutoff));
  const pwcontact::BatchOptions options = batch_options(precision, iterations, "standard", isa);
  const bool single = is_float32(r12) && is_float32(q1) && is_float32(q2) &&
                      (options.precision == pwcontact::Precision::automatic ||
                       options.precision == pwcontact::Precision::single_precision);
  if (single) return overlap_typed<float>(r12, q1, q2, cutoff, options, threads);
  return overlap_typed<double>(r12, q1, q2, cutoff, options, threads);
}

// Q from semi-axes (N, 3) and quaternions (N, 4) (w, x, y, z), either broadcast.
py::array_t<double> quadratic_form(const py::object& semi_axes_in,
                                   const py::object& orientation_in) {
  const Rows<double> axes = rows_of<double>(semi_axes_in, 3, "semi_axes");
  const Rows<double> q = rows_of<double>(orientation_in, 4, "orientation");
  const std::size_t n = common_rows({{axes.rows, axes.broadcast}, {q.rows, q.broadcast}},
                                    {"semi_axes", "orientation"});
  py::array_t<double> out({py::ssize_t(n), py::ssize_t(6)});
  double* data = out.mutable_data();
  // (Without the GIL: the first bad particle is noted, and named after.)
  std::size_t bad = n;
  std::string why;
  {
    py::gil_scoped_release release;
    for (std::size_t i = 0; i < n && bad == n; ++i) {
      const std::array<double, 3> a = {axes.at(i, 0), axes.at(i, 1), axes.at(i, 2)};
      for (int k = 0; k < 3 && bad == n; ++k)
        if (!(a[k] > 0) || !std::isfinite(a[k]))
          bad = i, why = "semi_axes must be positive and finite, got " +
                         pwcontact::detail::number_text(a[k]);
      if (bad != n) break;
      try {
        const pwcontact::QuadraticForm f = pwcontact::quadratic_form_from_quaternion(
            a, {q.at(i, 0), q.at(i, 1), q.at(i, 2), q.at(i, 3)});
        std::copy(f.begin(), f.end(), data + 6 * i);
      } catch (const std::invalid_argument& e) {
        bad = i, why = e.what();
      }
    }
  }
  if (bad != n) throw py::value_error("particle " + std::to_string(bad) + ": " + why);
  return out;
}

pwcontact::Box make_box(const py::object& box) {
  if (box.is_none()) return pwcontact::Box::open();
  const auto v = box.cast<std::vector<double>>();
  if (v.size() != 7)
    throw py::value_error("internal: a box is (Lx, Ly, Lz, xy, xz, yz, dimensions)");
  if (v[6] == 2) return pwcontact::Box::two_dimensional_box(v[0], v[1], v[3]);
  return pwcontact::Box::triclinic(v[0], v[1], v[2], v[3], v[4], v[5]);
}

// make_box's inverse: (Lx, Ly, Lz, xy, xz, yz, dimensions, periodic), as
// the Python package's _box_of reads it.
py::tuple box_tuple(const pwcontact::Box& b) {
  return py::make_tuple(b.length[0], b.length[1], b.length[2], b.tilt[0], b.tilt[1], b.tilt[2],
                        b.two_dimensional ? 2 : 3, b.periodic);
}

// A store from numpy arrays: forms q (N, 6); or semi-axes (N, 3 | 3,) and
// orientations (N, 4 | 4,); or per-type semi-axes (T, 3) and type_id (N,).
pwcontact::ParticleStore make_store(const py::object& positions_in,
                                    const py::object& orientations_in,
                                    const py::object& semi_axes_in, const py::object& q_in,
                                    const py::object& type_semi_axes_in,
                                    const py::object& typeid_in, int threads) {
  const Rows<double> positions = rows_of<double>(positions_in, 3, "positions");
  if (positions.broadcast) throw py::value_error("positions must have shape (N, 3)");
  const std::size_t n = positions.rows;
  pwcontact::ParticleStore store;
  const Rows<double> orientations = orientation_rows(orientations_in);
  expect_rows(orientations, n, "orientations");
  const int given =
      int(!semi_axes_in.is_none()) + int(!q_in.is_none()) + int(!type_semi_axes_in.is_none());
  if (given != 1)
    throw py::value_error("give the shapes one way: semi_axes, q, or type_semi_axes with typeid");
  auto centre = [&](std::size_t i) {
    return std::array<double, 3>{positions.at(i, 0), positions.at(i, 1), positions.at(i, 2)};
  };
  auto quaternion = [&](std::size_t i) {
    return std::array<double, 4>{orientations.at(i, 0), orientations.at(i, 1),
                                 orientations.at(i, 2), orientations.at(i, 3)};
  };
  // Every particle set by `set(i)`, over the threads, without the GIL.
  pwcontact::detail::ParallelErrors errors;
  auto fill = [&](auto&& set) {
    py::gil_scoped_release release;
    store.resize(n);
#pragma omp parallel for num_threads(threads) schedule(static)
    for (std::size_t i = 0; i < n; ++i) errors.run([&] { set(i); });
  };
  if (!q_in.is_none()) {
    const Rows<double> q = rows_of<double>(q_in, 6, "q");
    expect_rows(q, n, "q");
    fill([&](std::size_t i) {
      store.set(i, centre(i),
                {q.at(i, 0), q.at(i, 1), q.at(i, 2), q.at(i, 3), q.at(i, 4), q.at(i, 5)});
    });
  } else if (!semi_axes_in.is_none()) {
    const Rows<double> axes = rows_of<double>(semi_axes_in, 3, "semi_axes");
    expect_rows(axes, n, "semi_axes");
    if (axes.broadcast) {
      // One shape for all: a type, so that the scene is searched as identical shapes.
      const std::uint32_t type = store.add_type({axes.at(0, 0), axes.at(0, 1), axes.at(0, 2)});
      fill([&](std::size_t i) { store.set_typed(i, centre(i), type, quaternion(i)); });
    } else {
      fill([&](std::size_t i) {
        store.set_axes(i, centre(i), {axes.at(i, 0), axes.at(i, 1), axes.at(i, 2)}, quaternion(i));
      });
    }
  } else {
    if (typeid_in.is_none()) throw py::value_error("type_semi_axes needs typeid");
    const Rows<double> types = rows_of<double>(type_semi_axes_in, 3, "type_semi_axes");
    for (std::size_t t = 0; t < types.rows; ++t)
      store.add_type({types.at(t, 0), types.at(t, 1), types.at(t, 2)});
    auto typeid_array = py::array_t<std::uint32_t, py::array::forcecast>::ensure(typeid_in);
    if (!typeid_array || typeid_array.ndim() != 1 || std::size_t(typeid_array.shape(0)) != n)
      throw py::value_error("typeid must have shape (" + std::to_string(n) + ",)");
    const auto typeid_view = typeid_array.unchecked<1>();
    fill([&](std::size_t i) { store.set_typed(i, centre(i), typeid_view(i), quaternion(i)); });
  }
  errors.rethrow_if_failed();
  return store;
}

// The pairs as arrays: (M, 2) rows, per-particle counts and offsets, mu2
// (or None).
py::dict pair_arrays(const pwcontact::ScreenedPairs& pairs, std::size_t n, bool with_mu2) {
  const std::size_t m = pairs.size();
  py::array_t<std::uint32_t> out({py::ssize_t(m), py::ssize_t(2)});
  py::array_t<std::uint32_t> counts{py::ssize_t(n)};
  py::array_t<std::int64_t> offsets{py::ssize_t(n + 1)};
  py::array_t<double> mu2{py::ssize_t(with_mu2 ? m : 0)};
  std::uint32_t* const p = out.mutable_data();
  std::uint32_t* const c = counts.mutable_data();
  std::int64_t* const o = offsets.mutable_data();
  double* const mu2_out = mu2.mutable_data();
  {
    // One pass over the sorted pairs, without the GIL: the (i, j) rows, the
    // counts, and the offsets (pairs[offsets[k]:offsets[k + 1]] are those
    // (k, j > k)).
    py::gil_scoped_release release;
    std::fill(c, c + n, 0u);
    std::size_t next = 0;  // the first particle whose offset is not written
    for (std::size_t q = 0; q < m; ++q) {
      const std::uint32_t i = pairs.i[q], j = pairs.j[q];
      while (next <= i) o[next++] = std::int64_t(q);
      p[2 * q] = i;
      p[2 * q + 1] = j;
      ++c[i];
      ++c[j];
    }
    while (next <= n) o[next++] = std::int64_t(m);
    if (with_mu2) std::copy(pairs.mu2.begin(), pairs.mu2.end(), mu2_out);
  }
  py::dict d;
  d["pairs"] = out;
  d["counts"] = counts;
  d["offsets"] = offsets;
  if (with_mu2)
    d["mu2"] = mu2;
  else
    d["mu2"] = py::none();
  return d;
}

py::dict screened(const pwcontact::ScreenedPairs& pairs, std::size_t n, bool with_mu2,
                  const pwcontact::ScreenReport& report) {
  py::dict d = pair_arrays(pairs, n, with_mu2);
  py::dict r;
  r["candidate_pairs"] = report.candidate_pairs;
  r["solved"] = report.solved;
  r["invalid"] = report.invalid;
  r["found"] = report.found;
  r["threads"] = report.threads;
  r["seconds"] = report.seconds_total();
  d["report"] = r;
  return d;
}

py::dict screen(const py::object& positions, const py::object& orientations,
                const py::object& semi_axes, const py::object& q, const py::object& type_semi_axes,
                const py::object& type_id, const py::object& box, double cutoff, bool with_mu2,
                int threads, const py::object& workspace) {
  const int used = thread_count(threads);
  // (Cast before the GIL is let go; a workspace already serving a call from
  // another thread refuses this one with std::logic_error: RuntimeError.)
  pwcontact::ScreenWorkspace* kept =
      workspace.is_none() ? nullptr : &workspace.cast<pwcontact::ScreenWorkspace&>();
  pwcontact::ParticleStore store =
      make_store(positions, orientations, semi_axes, q, type_semi_axes, type_id, used);
  const pwcontact::Box b = make_box(box);
  pwcontact::ScreenOptions options;
  options.cutoff = cutoff;
  options.with_mu2 = with_mu2;
  options.threads = used;
  pwcontact::ScreenedPairs pairs;
  pwcontact::ScreenReport report;
  {
    py::gil_scoped_release release;
    report = kept ? pwcontact::screen_pairs(store, b, options, pairs, *kept)
                  : pwcontact::screen_pairs(store, b, options, pairs);
  }
  return screened(pairs, store.size(), with_mu2, report);
}

#if PWCONTACT_WITH_MPI
// The screen over the ranks of an MPI communicator (given by its Fortran
// handle, as mpi4py's Comm.py2f() gives it): this rank's particles, their
// global ids (tags; None: numbered by rank, rank 0's first), the pairs of
// this rank under the owner rule, or every rank's on rank 0 with gather.
// `local_error`: what the package's own checks of this rank's arguments
// found (empty: nothing). Every rank's input is checked before the first
// collective call, and an error on any rank is raised on every rank: this
// rank's own exception where it failed, a ValueError naming the rank on the
// others (a rank that raised alone left the others waiting for ever).
py::dict screen_mpi(const py::object& positions, const py::object& orientations,
                    const py::object& semi_axes, const py::object& q,
                    const py::object& type_semi_axes, const py::object& type_id,
                    const py::object& box, double cutoff, bool with_mu2, int threads,
                    std::int64_t comm_handle, const py::object& tags_in, bool gather,
                    const py::object& workspace, const std::string& local_error) {
  pwcontact::ScreenWorkspace* kept =
      workspace.is_none() ? nullptr : &workspace.cast<pwcontact::ScreenWorkspace&>();
  int initialized = 0, finalized = 0;
  MPI_Initialized(&initialized);
  MPI_Finalized(&finalized);
  if (!initialized || finalized)
    throw py::value_error(
        "comm: MPI is not initialised (import mpi4py.MPI first) or already "
        "finalised");
  const MPI_Comm comm = MPI_Comm_f2c(MPI_Fint(comm_handle));
  std::string error = local_error;
  std::exception_ptr own;
  int used = 1;
  pwcontact::ParticleStore store;
  std::vector<std::uint64_t> tags;
  pwcontact::Box b;
  if (error.empty()) {
    try {
      used = thread_count(threads);
      store = make_store(positions, orientations, semi_axes, q, type_semi_axes, type_id, used);
      if (!tags_in.is_none()) {
        auto given = py::array_t<std::uint64_t, py::array::forcecast>::ensure(tags_in);
        if (!given || given.ndim() != 1 || std::size_t(given.shape(0)) != store.size())
          throw py::value_error("tags must have shape (" + std::to_string(store.size()) + ",)");
        const auto view = given.unchecked<1>();
        tags.resize(store.size());
        for (std::size_t k = 0; k < store.size(); ++k) tags[k] = view(py::ssize_t(k));
      }
      b = make_box(box);
    } catch (const std::exception& e) {
      error = e.what();
      own = std::current_exception();
    }
  }
  try {
    pwcontact::mpi::detail::throw_if_any(comm, error, "screen");
  } catch (const std::invalid_argument&) {
    if (own) std::rethrow_exception(own);
    throw;
  }
  // gather, the same on every rank (the box and the options are checked
  // by the screen): a rank alone in gather_pairs would wait there for ever.
  // So must the choice of tags: ranks without them number their particles
  // by a scan the ranks with them would not join (a hang, or tags from a
  // mismatched collective).
  const int mine[2] = {gather ? 1 : 0, tags_in.is_none() ? 0 : 1};
  int all[2] = {0, 0};
  MPI_Allreduce(mine, all, 2, MPI_INT, MPI_SUM, comm);
  int ranks = 1;
  MPI_Comm_size(comm, &ranks);
  if (all[0] != 0 && all[0] != ranks)
    throw py::value_error("screen (MPI): gather is True on " + std::to_string(all[0]) + " of the " +
                          std::to_string(ranks) + " ranks; every rank must pass the same gather");
  if (all[1] != 0 && all[1] != ranks)
    throw py::value_error("screen (MPI): tags are given on " + std::to_string(all[1]) + " of the " +
                          std::to_string(ranks) +
                          " ranks; every rank must pass the same: tags on every rank, or on none");
  const std::size_t n = store.size();
  if (tags_in.is_none()) {
    tags.resize(n);
    unsigned long long count = n, first = 0;
    MPI_Exscan(&count, &first, 1, MPI_UNSIGNED_LONG_LONG, MPI_SUM, comm);
    int rank = 0;
    MPI_Comm_rank(comm, &rank);
    if (rank == 0) first = 0;  // (MPI_Exscan leaves rank 0's result undefined)
    for (std::size_t k = 0; k < n; ++k) tags[k] = first + k;
  }
  pwcontact::ScreenOptions options;
  options.cutoff = cutoff;
  options.with_mu2 = with_mu2;
  options.threads = used;
  pwcontact::mpi::TaggedPairs pairs;
  pwcontact::mpi::DistributedReport report;
  {
    py::gil_scoped_release release;
    report = kept ? pwcontact::mpi::screen_pairs(comm, store, tags, b, options, pairs, *kept)
                  : pwcontact::mpi::screen_pairs(comm, store, tags, b, options, pairs);
    if (gather) pairs = pwcontact::mpi::gather_pairs(comm, pairs);
  }
  const std::size_t m = pairs.size();
  py::array_t<std::uint64_t> out({py::ssize_t(m), py::ssize_t(2)});
  std::uint64_t* p = out.mutable_data();
  for (std::size_t k = 0; k < m; ++k) {
    p[2 * k] = pairs.i[k];
    p[2 * k + 1] = pairs.j[k];
  }
  py::dict d;
  d["pairs"] = out;
  if (with_mu2)
    d["mu2"] = py::array_t<double>(py::ssize_t(m), pairs.mu2.data());
  else
    d["mu2"] = py::none();
  py::dict r;
  r["dims"] = py::make_tuple(report.dims[0], report.dims[1], report.dims[2]);
  r["coords"] = py::make_tuple(report.coords[0], report.coords[1], report.coords[2]);
  r["given"] = report.given;
  r["owned"] = report.owned;
  r["sent_away"] = report.sent_away;
  r["ghosts"] = report.ghosts;
  r["neighbours"] = report.neighbours;
  r["ghost_bytes_sent"] = report.ghost_bytes_sent;
  r["migration_bytes_sent"] = report.migration_bytes_sent;
  r["seconds_migration"] = report.seconds_migration;
  r["seconds_ghosts"] = report.seconds_ghosts;
  r["seconds_screen"] = report.seconds_screen;
  d["report"] = r;
  return d;
}
#endif

// The store's centres (N, 3), or its forms (N, 6), as rows.
py::array_t<double> store_rows(const pwcontact::ParticleStore& store, bool forms) {
  const std::size_t n = store.size();
  const int k_count = forms ? 6 : 3;
  py::array_t<double> out({py::ssize_t(n), py::ssize_t(k_count)});
  auto o = out.mutable_unchecked<2>();
  for (int k = 0; k < k_count; ++k) {
    const std::vector<double>& column = forms ? store.q(k) : store.centre(k);
    for (std::size_t i = 0; i < n; ++i) o(i, k) = column[i];
  }
  return out;
}

// A scene file read by the C++ readers, as arrays.
py::dict scene_dict(const pwcontact::Scene& s) {
  py::dict d;
  d["positions"] = store_rows(s.particles, false);
  d["q"] = store_rows(s.particles, true);
  d["box"] = box_tuple(s.box);
  py::array_t<std::uint32_t> typeid_array{py::ssize_t(s.type_id.size())};
  std::copy(s.type_id.begin(), s.type_id.end(), typeid_array.mutable_data());
  d["typeid"] = typeid_array;
  d["type_names"] = s.type_names;
  py::array_t<std::uint64_t> id{py::ssize_t(s.id.size())};
  std::copy(s.id.begin(), s.id.end(), id.mutable_data());
  d["id"] = id;
  d["frame"] = s.frame;
  d["frames"] = s.frames;
  return d;
}

// N numbers of one particle (a position, a quaternion, a form): a numpy
// array through its buffer, with its shape checked; anything else by
// pybind11's cast of a sequence. A wrong count is a ValueError naming the
// argument (pybind11's cast error names neither it nor the count).
template <std::size_t N>
std::array<double, N> numbers(const py::object& given, const char* name) {
  std::array<double, N> out;
  if (py::isinstance<py::array>(given)) {
    const auto a = py::array_t<double, py::array::forcecast>::ensure(given);
    if (!a || a.ndim() != 1 || a.shape(0) != py::ssize_t(N))
      throw py::value_error(std::string(name) + " must have shape (" + std::to_string(N) + ",)");
    const auto v = a.unchecked<1>();
    for (std::size_t k = 0; k < N; ++k) out[k] = v(py::ssize_t(k));
    return out;
  }
  try {
    return given.cast<std::array<double, N>>();
  } catch (const py::cast_error&) {
    throw py::value_error(std::string(name) + " must be " + std::to_string(N) + " numbers");
  }
}

// The persistent scene of trial moves (moving_scene.hpp). Queries run
// without the GIL, so that another Python thread may call in meanwhile: they
// share `lock_`, and the calls that change the scene hold it alone (each
// takes it after releasing the GIL, and lets it go before taking the GIL
// back, so that neither waits on the other while holding both).
// A single query's `exclude`: a particle of the scene, or -1 for none (in
// C++: an index that no particle has, checked here while the scene is held,
// where the check costs nothing beside the query).
void check_exclude(const pwcontact::MovingScene& scene, std::int64_t exclude) {
  if (exclude != -1 && !(exclude >= 0 && std::uint64_t(exclude) < scene.size()))
    throw py::index_error("exclude: particle " + std::to_string(exclude) + " does not exist (" +
                          std::to_string(scene.size()) + " particles; -1 or None: none)");
}

class PyMovingScene {
 public:
  PyMovingScene(const py::object& positions, const py::object& orientations,
                const py::object& semi_axes, const py::object& q, const py::object& type_semi_axes,
                const py::object& type_id, const py::object& box)
      : scene_(make_store(positions, orientations, semi_axes, q, type_semi_axes, type_id, 1),
               make_box(box)) {}

  pwcontact::ParticleStore::Particle trial(const py::object& position,
                                           const py::object& orientation,
                                           const py::object& semi_axes, const py::object& q,
                                           const py::object& type_id) const {
    const auto c = numbers<3>(position, "position");
    const std::array<double, 4> o = orientation.is_none() ? std::array<double, 4>{1, 0, 0, 0}
                                                          : numbers<4>(orientation, "orientation");
    const int given = int(!semi_axes.is_none()) + int(!q.is_none()) + int(!type_id.is_none());
    if (given != 1) throw py::value_error("give the trial's shape one way: semi_axes, q or typeid");
    if (!q.is_none()) return scene_.trial(c, numbers<6>(q, "q"));
    if (!semi_axes.is_none()) return scene_.trial_axes(c, numbers<3>(semi_axes, "semi_axes"), o);
    return scene_.trial_typed(c, type_id.cast<std::uint32_t>(), o);
  }

  // Trial particles from arrays: positions (M, 3 | 3,) and one of
  // semi_axes (M, 3 | 3,) with orientations (M, 4 | 4,), or q (M, 6 | 6,):
  // M the arrays' common row count, a single row broadcast against the
  // others (as contact_function broadcasts); a bad one named by its row.
  std::vector<pwcontact::ParticleStore::Particle> trials(const py::object& positions_in,
                                                         const py::object& orientations_in,
                                                         const py::object& semi_axes_in,
                                                         const py::object& q_in,
                                                         const char* what = "trial") const {
    const Rows<double> positions = rows_of<double>(positions_in, 3, "positions");
    const int given = int(!semi_axes_in.is_none()) + int(!q_in.is_none());
    if (given != 1) throw py::value_error("give the trials' shapes one way: semi_axes or q");
    const Rows<double> orientations = orientation_rows(orientations_in);
    const Rows<double> shape = q_in.is_none() ? rows_of<double>(semi_axes_in, 3, "semi_axes")
                                              : rows_of<double>(q_in, 6, "q");
    const std::size_t m =
        common_rows({{positions.rows, positions.broadcast},
                     {orientations.rows, orientations.broadcast},
                     {shape.rows, shape.broadcast}},
                    {"positions", "orientations", q_in.is_none() ? "semi_axes" : "q"});
    std::vector<pwcontact::ParticleStore::Particle> out;
    out.reserve(m);
    for (std::size_t k = 0; k < m; ++k) {
      const std::string who = what + (" " + std::to_string(k));
      const std::array<double, 3> c = {positions.at(k, 0), positions.at(k, 1), positions.at(k, 2)};
      if (q_in.is_none())
        out.push_back(pwcontact::ParticleStore::particle_axes(
            c, {shape.at(k, 0), shape.at(k, 1), shape.at(k, 2)},
            {orientations.at(k, 0), orientations.at(k, 1), orientations.at(k, 2),
             orientations.at(k, 3)},
            who));
      else
        out.push_back(
            pwcontact::ParticleStore::particle(c,
                                               {shape.at(k, 0), shape.at(k, 1), shape.at(k, 2),
                                                shape.at(k, 3), shape.at(k, 4), shape.at(k, 5)},
                                               who));
    }
    return out;
  }

  // f(scene) with the GIL released, under the shared lock (queries) or the
  // exclusive one (changes).
  template <class F>
  auto query(F&& f) const {
    py::gil_scoped_release release;
    std::shared_lock<std::shared_mutex> hold(lock_);
    return f(scene_);
  }
  // The shared lock, taken with the GIL held (for reads that build Python
  // objects): a change holding the exclusive lock never waits for the GIL.
  std::shared_lock<std::shared_mutex> reading() const {
    py::gil_scoped_release release;
    return std::shared_lock<std::shared_mutex>(lock_);
  }
  template <class F>
  auto change(F&& f) {
    py::gil_scoped_release release;
    std::unique_lock<std::shared_mutex> hold(lock_);
    return f(scene_);
  }

  pwcontact::MovingScene scene_;

 private:
  mutable std::shared_mutex lock_;
};

// The neighbour list with a skin (neighbor_list.hpp), kept across calls of
// update; one update at a time (another Python thread's waits), without
// the GIL.
class PySkinNeighborList {
 public:
  PySkinNeighborList(double cutoff, double skin, bool warm_start, int threads)
      : list_(options(cutoff, skin, warm_start, threads)) {}

  py::dict update(const py::object& positions, const py::object& orientations,
                  const py::object& semi_axes, const py::object& q,
                  const py::object& type_semi_axes, const py::object& type_id,
                  const py::object& box) {
    const int used = thread_count(list_.options().threads);
    const pwcontact::ParticleStore store =
        make_store(positions, orientations, semi_axes, q, type_semi_axes, type_id, used);
    const pwcontact::Box b = make_box(box);
    pwcontact::ScreenedPairs pairs;
    pwcontact::SkinReport report;
    {
      py::gil_scoped_release release;
      std::lock_guard<std::mutex> hold(lock_);
      report = list_.update(store, b, pairs);
    }
    py::dict d = pair_arrays(pairs, store.size(), true);
    py::dict r;
    r["rebuilt"] = report.rebuilt;
    r["largest_move"] = report.largest_move;
    r["listed"] = report.listed;
    r["solved"] = report.solved;
    r["found"] = report.found;
    r["mean_evaluations"] = report.mean_evaluations;
    r["seconds_solve"] = report.seconds_solve;
    r["seconds"] = report.seconds_total;
    d["report"] = r;
    return d;
  }

  std::size_t rebuilds() const { return list_.rebuilds(); }

 private:
  static pwcontact::SkinOptions options(double cutoff, double skin, bool warm_start, int threads) {
    pwcontact::SkinOptions o;
    o.cutoff = cutoff;
    o.skin = skin;
    o.warm_start = warm_start;
    o.threads = thread_count(threads);
    return o;
  }
  pwcontact::SkinNeighborList list_;
  std::mutex lock_;
};

// The hard-particle Monte Carlo example (monte_carlo.hpp). Every call takes
// `lock_` after releasing the GIL (one call at a time; another Python
// thread's waits without holding the GIL). The lock is recursive: the
// progress callback of compress_to_packing, called between sweeps in the
// calling thread, may read the state (or sweep) itself.
class PyHardParticleMC {
 public:
  static pwcontact::HardParticleMCOptions options(double packing, double translation,
                                                  double rotation, bool adapt_steps,
                                                  std::uint64_t seed, int threads) {
    pwcontact::HardParticleMCOptions o;
    o.packing = packing;
    o.translation = translation;
    o.rotation = rotation;
    o.adapt_steps = adapt_steps;
    o.seed = seed;
    o.threads = thread_count(threads);
    return o;
  }

  // From arrays: positions (N, 3), semi_axes (N, 3 | 3,), orientations
  // (N, 4 | 4, | None).
  static PyHardParticleMC from_arrays(const py::object& positions_in,
                                      const py::object& orientations_in,
                                      const py::object& semi_axes_in, const py::object& box,
                                      const pwcontact::HardParticleMCOptions& o) {
    const Rows<double> positions = rows_of<double>(positions_in, 3, "positions");
    if (positions.broadcast) throw py::value_error("positions must have shape (N, 3)");
    const std::size_t n = positions.rows;
    const Rows<double> orientations = orientation_rows(orientations_in);
    expect_rows(orientations, n, "orientations");
    const Rows<double> axes = rows_of<double>(semi_axes_in, 3, "semi_axes");
    expect_rows(axes, n, "semi_axes");
    std::vector<std::array<double, 3>> centre(n), semi_axes(n);
    std::vector<std::array<double, 4>> orientation(n);
    for (std::size_t i = 0; i < n; ++i) {
      for (int k = 0; k < 3; ++k)
        centre[i][k] = positions.at(i, k), semi_axes[i][k] = axes.at(i, k);
      for (int k = 0; k < 4; ++k) orientation[i][k] = orientations.at(i, k);
    }
    const pwcontact::Box b = make_box(box);
    py::gil_scoped_release release;
    return PyHardParticleMC(pwcontact::HardParticleMC(b, std::move(centre), std::move(semi_axes),
                                                      std::move(orientation), o));
  }

  explicit PyHardParticleMC(pwcontact::HardParticleMC mc) : mc_(std::move(mc)) {}
  PyHardParticleMC(PyHardParticleMC&& other) noexcept : mc_(std::move(other.mc_)) {}

  // f(mc) with the GIL released and the lock held.
  template <class F>
  auto run(F&& f) {
    py::gil_scoped_release release;
    std::lock_guard<std::recursive_mutex> hold(lock_);
    return f(mc_);
  }
  // The lock, taken without the GIL (for reads that build Python objects).
  std::unique_lock<std::recursive_mutex> reading() {
    py::gil_scoped_release release;
    return std::unique_lock<std::recursive_mutex>(lock_);
  }

  py::dict sweep() {
    const pwcontact::SweepReport r = run([](pwcontact::HardParticleMC& mc) { return mc.sweep(); });
    py::dict d;
    d["proposed"] = r.proposed;
    d["accepted"] = r.accepted;
    d["left_domain"] = r.left_domain;
    d["deferred"] = r.deferred;
    d["seconds"] = r.seconds;
    return d;
  }

  // progress(sweeps, packing, acceptance) after each sweep, with the GIL.
  void compress_to_packing(std::size_t max_sweeps, const py::object& progress) {
    std::function<void(std::size_t, double, double)> call;
    if (!progress.is_none())
      call = [&progress](std::size_t sweeps, double packing, double acceptance) {
        py::gil_scoped_acquire acquire;
        progress(sweeps, packing, acceptance);
      };
    run([&](pwcontact::HardParticleMC& mc) { mc.compress_to_packing(max_sweeps, call); });
  }

  py::dict state() {
    const auto hold = reading();
    const std::size_t n = mc_.semi_axes().size();
    py::array_t<double> axes({py::ssize_t(n), py::ssize_t(3)}),
        orientations({py::ssize_t(n), py::ssize_t(4)});
    auto a = axes.mutable_unchecked<2>();
    auto o = orientations.mutable_unchecked<2>();
    for (std::size_t i = 0; i < n; ++i) {
      for (int k = 0; k < 3; ++k) a(i, k) = mc_.semi_axes()[i][k];
      for (int k = 0; k < 4; ++k) o(i, k) = mc_.orientation()[i][k];
    }
    const pwcontact::Box& b = mc_.box();
    py::dict d;
    d["positions"] = store_rows(mc_.particles(), false);
    d["orientations"] = orientations;
    d["semi_axes"] = axes;
    d["box"] = box_tuple(b);
    return d;
  }

  pwcontact::HardParticleMC mc_;

 private:
  std::recursive_mutex lock_;
};

// Seconds of the C++ calls the Python ones are measured against
// (bench/python_overhead.py): the same numbers, already in the layout the
// C++ API takes (SoA pairs; a ParticleStore), set up outside the timing.
double now_seconds() { return omp_get_wtime(); }

double time_batch(const py::array_t<double, py::array::c_style | py::array::forcecast>& r12,
                  const py::array_t<double, py::array::c_style | py::array::forcecast>& q1,
                  const py::array_t<double, py::array::c_style | py::array::forcecast>& q2,
                  int threads, bool rows, bool fresh_outputs) {
  const std::size_t n = std::size_t(r12.shape(0));
  pwcontact::PairBatch<double> batch(rows ? 0 : n);
  pwcontact::PairBatchView<double> view;
  if (rows) {  // the C-ordered arrays in place (strided view)
    view.size = n;
    for (int k = 0; k < 3; ++k) view.r12[k] = r12.data() + k;
    for (int k = 0; k < 6; ++k) view.q1[k] = q1.data() + k, view.q2[k] = q2.data() + k;
    view.r12_stride = 3;
    view.q1_stride = view.q2_stride = 6;
  } else {  // columns of their own
    for (std::size_t i = 0; i < n; ++i)
      batch.set(i, r12.data() + 3 * i, q1.data() + 6 * i, q2.data() + 6 * i);
    view = batch.view();
  }
  // Outputs written before the clock starts (as out= arrays reused are), or
  // allocated within the timing and first touched by the call (as the
  // binding's new result arrays are).
  std::vector<double> mu2(fresh_outputs ? 0 : n), lambda(fresh_outputs ? 0 : n);
  std::vector<Status> status(fresh_outputs ? 0 : n);
  pwcontact::BatchOptions options;
  options.threads = thread_count(threads);
  py::gil_scoped_release release;
  const double start = now_seconds();
  if (fresh_outputs) {
    std::unique_ptr<double[]> m(new double[n]), l(new double[n]);
    std::unique_ptr<Status[]> st(new Status[n]);
    pwcontact::contact_function_batch(view, {m.get(), l.get(), st.get()}, options);
    return now_seconds() - start;
  }
  pwcontact::contact_function_batch(view, {mu2.data(), lambda.data(), status.data()}, options);
  return now_seconds() - start;
}

// (seconds of screen_pairs, seconds of building the store from the arrays)
std::pair<double, double> time_screen(const py::object& positions, const py::object& orientations,
                                      const py::object& semi_axes, const py::object& box,
                                      double cutoff, int threads) {
  const int used = thread_count(threads);
  const double build_start = now_seconds();
  const pwcontact::ParticleStore store =
      make_store(positions, orientations, semi_axes, py::none(), py::none(), py::none(), used);
  const double built = now_seconds() - build_start;
  pwcontact::ScreenOptions options;
  options.cutoff = cutoff;
  options.threads = used;
  pwcontact::ScreenedPairs pairs;
  const pwcontact::Box b = make_box(box);
  py::gil_scoped_release release;
  const double start = now_seconds();
  pwcontact::screen_pairs(store, b, options, pairs);
  return {now_seconds() - start, built};
}

}  // namespace

PYBIND11_MODULE(_pwcontact, m) {
  m.doc() = "pwcontact's compiled core; use the pwcontact package.";
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const std::invalid_argument& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const std::out_of_range& e) {
      PyErr_SetString(PyExc_IndexError, e.what());
    }
  });
  m.def("contact_function", &contact_function, py::arg("r12"), py::arg("q1"), py::arg("q2"),
        py::arg("outputs"), py::arg("precision"), py::arg("iterations"), py::arg("accuracy"),
        py::arg("threads"), py::arg("isa"), py::arg("lambda_start"), py::arg("out"));
  m.def("overlap", &overlap, py::arg("r12"), py::arg("q1"), py::arg("q2"), py::arg("cutoff"),
        py::arg("precision"), py::arg("iterations"), py::arg("threads"), py::arg("isa"));
  m.def("quadratic_form", &quadratic_form, py::arg("semi_axes"), py::arg("orientation"));
  m.def("screen", &screen, py::arg("positions"), py::arg("orientations"), py::arg("semi_axes"),
        py::arg("q"), py::arg("type_semi_axes"), py::arg("typeid"), py::arg("box"),
        py::arg("cutoff"), py::arg("with_mu2"), py::arg("threads"), py::arg("workspace"));
  py::class_<pwcontact::ScreenWorkspace>(m, "ScreenWorkspace")
      .def(py::init<>())
      .def_property_readonly("bytes", &pwcontact::ScreenWorkspace::bytes)
      .def("release", &pwcontact::ScreenWorkspace::release);
#if PWCONTACT_WITH_MPI
  m.attr("with_mpi") = true;
  m.def("screen_mpi", &screen_mpi, py::arg("positions"), py::arg("orientations"),
        py::arg("semi_axes"), py::arg("q"), py::arg("type_semi_axes"), py::arg("typeid"),
        py::arg("box"), py::arg("cutoff"), py::arg("with_mu2"), py::arg("threads"), py::arg("comm"),
        py::arg("tags"), py::arg("gather"), py::arg("workspace"),
        py::arg("local_error") = std::string());
#else
  m.attr("with_mpi") = false;
#endif
  m.def("read_gsd", [](const std::string& path, std::int64_t frame) {
    pwcontact::Scene s;
    {
      py::gil_scoped_release release;
      s = pwcontact::read_gsd(path, frame);
    }
    return scene_dict(s);
  });
  m.def("read_lammps_data", [](const std::string& path) {
    pwcontact::Scene s;
    {
      py::gil_scoped_release release;
      s = pwcontact::read_lammps_data(path);
    }
    return scene_dict(s);
  });
  m.def("read_lammps_dump", [](const std::string& path, std::int64_t frame,
                               const std::map<std::string, std::string>& names) {
    // Column names by what they hold (x y z, shapex shapey shapez, quatw
    // quati quatj quatk), as the command line's --columns.
    pwcontact::LammpsColumns columns;
    const char* position[3] = {"x", "y", "z"};
    const char* shape[3] = {"shapex", "shapey", "shapez"};
    const char* quaternion[4] = {"quatw", "quati", "quatj", "quatk"};
    std::size_t used = 0;
    auto take = [&](const char* key, std::string& into) {
      if (const auto it = names.find(key); it != names.end()) into = it->second, ++used;
    };
    for (int k = 0; k < 3; ++k)
      take(position[k], columns.position[k]), take(shape[k], columns.shape[k]);
    for (int k = 0; k < 4; ++k) take(quaternion[k], columns.quaternion[k]);
    if (used != names.size()) {
      std::string unknown;
      for (const auto& [key, value] : names) {
        bool known = false;
        for (const char* k : position) known |= key == k;
        for (const char* k : shape) known |= key == k;
        for (const char* k : quaternion) known |= key == k;
        if (!known) unknown += (unknown.empty() ? "" : ", ") + key;
      }
      throw py::value_error("columns: unknown keys " + unknown +
                            " (keys: x y z shapex shapey shapez quatw quati quatj quatk)");
    }
    pwcontact::Scene s;
    {
      py::gil_scoped_release release;
      s = pwcontact::read_lammps_dump(path, frame, columns);
    }
    return scene_dict(s);
  });
  // The scalar reference path for one pair (as a per-pair binding is used).
  m.def(
      "reference",
      [](const std::array<double, 3>& r12, const std::array<double, 6>& q1,
         const std::array<double, 6>& q2) {
        const pwcontact::ContactResult<double> r =
            pwcontact::contact_function<double>(r12.data(), q1.data(), q2.data());
        return py::make_tuple(r.mu2, r.lambda, int(r.status));
      },
      py::arg("r12"), py::arg("q1"), py::arg("q2"));
  m.def("_time_batch", &time_batch, py::arg("r12"), py::arg("q1"), py::arg("q2"),
        py::arg("threads"), py::arg("rows") = false, py::arg("fresh_outputs") = false);
  m.def("_time_screen", &time_screen);
  m.def("status_names", [] {
    std::vector<std::pair<std::string, std::string>> names;
    for (int s = 0; s < pwcontact::status_count; ++s)
      names.emplace_back(pwcontact::status_name(Status(s)),
                         pwcontact::status_description(Status(s)));
    return names;
  });
  m.def("supported_isas", [] {
    std::vector<std::string> names;
    for (pwcontact::Isa isa : pwcontact::supported_isas())
      names.emplace_back(pwcontact::isa_name(isa));
    return names;
  });
  m.def("spheroid_scene", [](std::size_t n, std::uint64_t seed, double packing, double max_aspect) {
    pwcontact::SpheroidScene s;
    {
      py::gil_scoped_release release;
      s = pwcontact::spheroid_scene(n, seed, packing, max_aspect);
    }
    py::array_t<double> positions({py::ssize_t(n), py::ssize_t(3)}),
        axes({py::ssize_t(n), py::ssize_t(3)}), orientations({py::ssize_t(n), py::ssize_t(4)});
    auto p = positions.mutable_unchecked<2>();
    auto a = axes.mutable_unchecked<2>();
    auto o = orientations.mutable_unchecked<2>();
    for (std::size_t i = 0; i < n; ++i) {
      for (int k = 0; k < 3; ++k) p(i, k) = s.particles.centre(k)[i], a(i, k) = s.semi_axes[i][k];
      for (int k = 0; k < 4; ++k) o(i, k) = s.orientation[i][k];
    }
    py::dict d;
    d["positions"] = positions;
    d["orientations"] = orientations;
    d["semi_axes"] = axes;
    d["box"] = box_tuple(s.box);
    return d;
  });

  py::class_<pwcontact::ParticleStore::Particle>(m, "Particle");
  py::class_<PyMovingScene>(m, "MovingScene")
      .def(py::init<const py::object&, const py::object&, const py::object&, const py::object&,
                    const py::object&, const py::object&, const py::object&>(),
           py::arg("positions"), py::arg("orientations"), py::arg("semi_axes"), py::arg("q"),
           py::arg("type_semi_axes"), py::arg("typeid"), py::arg("box"))
      .def("__len__",
           [](const PyMovingScene& s) {
             const auto hold = s.reading();
             return s.scene_.size();
           })
      .def("trial", &PyMovingScene::trial, py::arg("position"), py::arg("orientation"),
           py::arg("semi_axes"), py::arg("q"), py::arg("typeid"))
      .def("insert",
           [](PyMovingScene& s, const pwcontact::ParticleStore::Particle& p) {
             return s.change([&](pwcontact::MovingScene& scene) { return scene.insert(p); });
           })
      .def("remove",
           [](PyMovingScene& s, std::size_t i) {
             return s.change([&](pwcontact::MovingScene& scene) { return scene.remove(i); });
           })
      .def("move",
           [](PyMovingScene& s, std::size_t i, const pwcontact::ParticleStore::Particle& p) {
             s.change([&](pwcontact::MovingScene& scene) { scene.move(i, p); });
           })
      .def("overlaps",
           [](const PyMovingScene& s, const pwcontact::ParticleStore::Particle& p,
              std::int64_t exclude) {
             return s.query([&](const pwcontact::MovingScene& scene) {
               check_exclude(scene, exclude);
               return scene.overlaps(p, exclude);
             });
           })
      .def("overlap_count",
           [](const PyMovingScene& s, const pwcontact::ParticleStore::Particle& p,
              std::int64_t exclude) {
             return s.query([&](const pwcontact::MovingScene& scene) {
               check_exclude(scene, exclude);
               return scene.overlap_count(p, exclude);
             });
           })
      .def("neighbors",
           [](const PyMovingScene& s, const pwcontact::ParticleStore::Particle& p, double cutoff,
              bool with_mu2, std::int64_t exclude) {
             const std::vector<pwcontact::Neighbor> found =
                 s.query([&](const pwcontact::MovingScene& scene) {
                   check_exclude(scene, exclude);
                   return scene.neighbors(p, cutoff, with_mu2, exclude);
                 });
             py::array_t<std::uint32_t> index{py::ssize_t(found.size())};
             py::array_t<double> mu2{py::ssize_t(found.size())};
             for (std::size_t k = 0; k < found.size(); ++k) {
               index.mutable_data()[k] = found[k].index;
               mu2.mutable_data()[k] = found[k].mu2;
             }
             return py::make_tuple(index, mu2);
           })
      .def("overlaps_many",
           [](const PyMovingScene& s, const py::object& positions, const py::object& orientations,
              const py::object& semi_axes, const py::object& q, const py::object& exclude_in,
              int threads) {
             const std::vector<pwcontact::ParticleStore::Particle> trials =
                 s.trials(positions, orientations, semi_axes, q);
             const std::size_t m = trials.size();
             py::array_t<std::int64_t, py::array::c_style | py::array::forcecast> exclude;
             if (!exclude_in.is_none()) {
               exclude =
                   py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>::ensure(
                       exclude_in);
               if (!exclude || exclude.ndim() != 1 || std::size_t(exclude.shape(0)) != m)
                 throw py::value_error("exclude must have shape (" + std::to_string(m) + ",)");
             }
             const std::int64_t* exclude_data = exclude_in.is_none() ? nullptr : exclude.data();
             py::array_t<std::int64_t> first{py::ssize_t(m)};
             std::int64_t* first_data = first.mutable_data();
             const int used = thread_count(threads);
             s.query([&](const pwcontact::MovingScene& scene) {
               scene.overlaps(trials.data(), exclude_data, m, first_data, used);
             });
             return first;
           })
      .def("move_many",
           [](PyMovingScene& s, const py::object& index_in, const py::object& positions,
              const py::object& orientations, const py::object& semi_axes, const py::object& q,
              int threads) {
             const std::vector<pwcontact::ParticleStore::Particle> moved =
                 s.trials(positions, orientations, semi_axes, q, "move");
             const std::size_t m = moved.size();
             const auto given =
                 py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>::ensure(
                     index_in);
             if (!given || given.ndim() != 1 || std::size_t(given.shape(0)) != m)
               throw py::value_error("indices must have shape (" + std::to_string(m) +
                                     ",), one per row of positions");
             const std::vector<std::int64_t> given_index(given.data(), given.data() + m);
             const int used = thread_count(threads);
             s.change([&](pwcontact::MovingScene& scene) {
               // Checked as int64 first (a negative index would wrap as
               // uint32); MovingScene::move_many checks every move before any.
               std::vector<std::uint32_t> index(m);
               for (std::size_t k = 0; k < m; ++k) {
                 const std::int64_t i = given_index[k];
                 if (i < 0 || std::uint64_t(i) >= std::uint64_t(scene.size()))
                   throw std::out_of_range("move " + std::to_string(k) + ": particle " +
                                           std::to_string(i) + " does not exist (" +
                                           std::to_string(scene.size()) + " particles)");
                 index[k] = std::uint32_t(i);
               }
               scene.move_many(index.data(), moved.data(), m, used);
             });
           })
      .def("positions",
           [](const PyMovingScene& s) {
             const auto hold = s.reading();
             return store_rows(s.scene_.particles(), false);
           })
      .def("q", [](const PyMovingScene& s) {
        const auto hold = s.reading();
        return store_rows(s.scene_.particles(), true);
      });

  py::class_<PyHardParticleMC>(m, "HardParticleMC")
      .def(py::init([](const py::object& positions, const py::object& orientations,
                       const py::object& semi_axes, const py::object& box, double packing,
                       double translation, double rotation, bool adapt_steps, std::uint64_t seed,
                       int threads) {
             return PyHardParticleMC::from_arrays(
                 positions, orientations, semi_axes, box,
                 PyHardParticleMC::options(packing, translation, rotation, adapt_steps, seed,
                                           threads));
           }),
           py::arg("positions"), py::arg("orientations"), py::arg("semi_axes"), py::arg("box"),
           py::arg("packing"), py::arg("translation"), py::arg("rotation"), py::arg("adapt_steps"),
           py::arg("seed"), py::arg("threads"))
      .def_static(
          "dilute_spheroids",
          [](std::size_t n, std::uint64_t seed, double max_aspect, double packing,
             double translation, double rotation, bool adapt_steps, int threads,
             std::size_t shapes) {
            const pwcontact::HardParticleMCOptions o = PyHardParticleMC::options(
                packing, translation, rotation, adapt_steps, seed, threads);
            py::gil_scoped_release release;
            return PyHardParticleMC(
                pwcontact::HardParticleMC::dilute_spheroids(n, seed, max_aspect, o, shapes));
          },
          py::arg("n"), py::arg("seed"), py::arg("max_aspect"), py::arg("packing"),
          py::arg("translation"), py::arg("rotation"), py::arg("adapt_steps"), py::arg("threads"),
          py::arg("shapes") = std::size_t(0))
      .def("sweep", &PyHardParticleMC::sweep)
      .def("compress",
           [](PyHardParticleMC& s) {
             return s.run([](pwcontact::HardParticleMC& mc) { return mc.compress(); });
           })
      .def("compress_to_packing", &PyHardParticleMC::compress_to_packing, py::arg("max_sweeps"),
           py::arg("progress"))
      .def("overlapping_pairs",
           [](PyHardParticleMC& s) {
             return s.run([](pwcontact::HardParticleMC& mc) { return mc.overlapping_pairs(); });
           })
      .def("state", &PyHardParticleMC::state)
      .def("numbers", [](PyHardParticleMC& s) {
        const auto hold = s.reading();
        py::dict d;
        d["packing"] = s.mc_.packing();
        d["translation"] = s.mc_.translation();
        d["rotation"] = s.mc_.rotation();
        d["sweeps"] = s.mc_.sweeps();
        return d;
      });

  py::class_<PySkinNeighborList>(m, "SkinNeighborList")
      .def(py::init<double, double, bool, int>(), py::arg("cutoff"), py::arg("skin"),
           py::arg("warm_start"), py::arg("threads"))
      .def("update", &PySkinNeighborList::update, py::arg("positions"), py::arg("orientations"),
           py::arg("semi_axes"), py::arg("q"), py::arg("type_semi_axes"), py::arg("typeid"),
           py::arg("box"))
      .def_property_readonly("rebuilds", &PySkinNeighborList::rebuilds);
}
