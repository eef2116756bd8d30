// The `lgp._lgp` extension: the engine behind the Python package (frontends/python/lgp). It
// speaks JSON text and numpy arrays; the package builds the objects users see. Every function
// goes through the same C++ calls as the CLI (config parsing and validation, table checks, the
// search, frontToJson, the emitters), so the messages and the results are the CLI's.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <initializer_list>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "lgp/config/config.hpp"
#include "lgp/config/json_reader.hpp"
#include "lgp/core/formula.hpp"
#include "lgp/eval/interpreter.hpp"
#include "lgp/io/result.hpp"
#include "lgp/search/search.hpp"
#include "lgp/search/two_step.hpp"
#include "run_pipeline.hpp"
#include "table_source.hpp"
#ifdef LGP_HAVE_EMIT
#include "lgp/emit/emit.hpp"
#include "lgp/emit/gpu_cost.hpp"
#endif
#ifdef LGP_HAVE_DATASETS
#include "lgp/datasets/generate.hpp"
#include "lgp/datasets/scene.hpp"
#endif

namespace py = pybind11;
namespace fs = std::filesystem;

namespace {

using Matrix = py::array_t<double, py::array::c_style | py::array::forcecast>;

[[noreturn]] void valueError(const std::string& msg) {
  throw py::value_error(msg);
}

template <class T>
T orRaise(lgp::Expected<T> e) {
  if (!e) valueError(e.error());
  return std::move(*e);
}

nlohmann::json parseText(const std::string& text, const std::string& what) {
  auto j = lgp::parseJson(text);
  if (!j) valueError(what + ": " + j.error());
  return std::move(*j);
}

// Columns of a 2-D array (rows x columns) as the table's [column][row] vectors.
std::vector<std::vector<double>> columns(const Matrix& a, const char* what, size_t want_cols) {
  if (a.ndim() != 2) valueError(std::string(what) + ": must be a 2-D array (rows x columns)");
  const size_t rows = a.shape(0), cols = a.shape(1);
  if (cols != want_cols)
    valueError(std::string(what) + ": has " + std::to_string(cols) + " columns, expected " +
               std::to_string(want_cols));
  std::vector<std::vector<double>> out(cols, std::vector<double>(rows));
  auto v = a.unchecked<2>();
  for (size_t r = 0; r < rows; ++r)
    for (size_t c = 0; c < cols; ++c) out[c][r] = v(r, c);
  return out;
}

Matrix toMatrix(const std::vector<std::vector<double>>& cols, size_t rows) {
  Matrix a({rows, cols.size()});
  auto m = a.mutable_unchecked<2>();
  for (size_t c = 0; c < cols.size(); ++c)
    for (size_t r = 0; r < rows; ++r) m(r, c) = cols[c][r];
  return a;
}

// The table of a fit from arrays: X (rows x inputs), Y (rows x outputs), optional weights,
// checked as `lgp run` checks a file's table (values, then the float32 evaluation's range).
lgp::Table arrayTable(const lgp::RunConfig& cfg, const Matrix& x, const Matrix& y,
                      const std::optional<Matrix>& w) {
  lgp::Table t;
  t.input_names = cfg.data.inputs;
  t.output_names = cfg.data.outputs;
  t.inputs = columns(x, "X", t.input_names.size());
  t.outputs = columns(y, "y", t.output_names.size());
  if (x.shape(0) != y.shape(0))
    valueError("y: has " + std::to_string(y.shape(0)) + " rows, X has " +
               std::to_string(x.shape(0)));
  if (w) {
    auto wc = columns(*w, "sample_weight", 1);
    if (wc[0].size() != t.rows())
      valueError("sample_weight: has " + std::to_string(wc[0].size()) + " rows, X has " +
                 std::to_string(t.rows()));
    t.weights = std::move(wc[0]);
  }
  t.meta["source"] = "arrays";
  if (auto st = t.validate(); !st) valueError("data: " + st.message());
  if (auto st = lgp::checkErrorNumerics(t, cfg.errorConfig(t.output_names)); !st)
    valueError("y: " + st.message());
  if (auto st = cfg.validateShape(t.numOutputs()); !st) valueError(st.message());
  return t;
}

lgp::RunConfig parseConfig(const std::string& text, const std::string& base_dir) {
  auto cfg = lgp::parseRunConfig(parseText(text, "config"), fs::path(base_dir));
  if (!cfg) valueError(cfg.error());
  if (auto st = cfg->validate(); !st) valueError(st.message());
  return std::move(*cfg);
}

// Calls Python every `interval` seconds while the search runs without the GIL: the progress
// callback, and the signal check that turns Ctrl-C into a stop request. A second Ctrl-C
// raises KeyboardInterrupt at once.
class PythonTicker {
 public:
  PythonTicker(py::object progress, double interval) : progress_(progress), interval_(interval) {}
  // With the GIL released; `force`: now, whatever the time since the last call.
  void tick(const std::function<lgp::SearchProgress()>& progress, bool force,
            const std::function<void()>& stop) {
    const auto now = std::chrono::steady_clock::now();
    const bool check = force || now - last_check_ >= std::chrono::milliseconds(50);
    if (!check) return;
    last_check_ = now;
    py::gil_scoped_acquire gil;
    if (PyErr_CheckSignals() != 0) {
      py::error_already_set e;
      if (!e.matches(PyExc_KeyboardInterrupt) || interrupted_) throw e;
      interrupted_ = true;
      stop();
    }
    if (!progress_.is_none() &&
        (force || std::chrono::duration<double>(now - last_progress_).count() >= interval_)) {
      last_progress_ = now;
      progress_(lgp::progressToJson(progress()).dump());
    }
  }
  bool interrupted() const { return interrupted_; }

 private:
  py::object progress_;
  double interval_;
  bool interrupted_ = false;
  std::chrono::steady_clock::time_point last_check_{}, last_progress_{};
};

// Ctrl-C while a scene's table is generated without the GIL: GenerateOptions::stop runs on
// OpenMP's threads; on the calling thread (the team's master, Python's main thread) it checks
// Python's signals under the GIL at most every 50 ms. A raised exception ends the generation
// and is raised again once the GIL is back (rethrow()).
class GenerationInterrupt {
 public:
  bool operator()() {
    if (raised_.load(std::memory_order_relaxed)) return true;
    if (std::this_thread::get_id() != caller_) return false;
    const auto now = std::chrono::steady_clock::now();
    if (now - last_ < std::chrono::milliseconds(50)) return false;
    last_ = now;
    py::gil_scoped_acquire gil;
    if (PyErr_CheckSignals() == 0) return false;
    error_ = std::make_unique<py::error_already_set>();
    raised_.store(true);
    return true;
  }
  // With the GIL held, after the generation: the exception a signal handler raised, if any.
  void rethrow() {
    if (error_) throw std::move(*error_);
  }

 private:
  const std::thread::id caller_ = std::this_thread::get_id();
  std::chrono::steady_clock::time_point last_{};
  std::atomic<bool> raised_{false};
  std::unique_ptr<py::error_already_set> error_;
};

// Runs a search. Data: X and y given (the config's data.inputs/outputs name their columns), or
// the config's own data.path / data.scene. Returns (front JSON text, interrupted).
py::tuple run(const std::string& config_text, const std::string& base_dir, std::optional<Matrix> x,
              std::optional<Matrix> y, std::optional<Matrix> w, py::object progress,
              double progress_interval) {
  lgp::RunConfig cfg = parseConfig(config_text, base_dir);
  // The run pipeline (run_pipeline.hpp), with arrays as a table source and Python's progress
  // callback and KeyboardInterrupt as the display.
  lgp::Table table = x ? arrayTable(cfg, *x, *y, w) : [&] {
    GenerationInterrupt interrupt;
    lgp::cli::TableLoadOptions load;
    load.stop = [&interrupt] { return interrupt(); };
    lgp::Expected<lgp::Table> t = lgp::Status::error("not loaded");
    {
      py::gil_scoped_release nogil;
      t = lgp::cli::loadRunTable(cfg, load);
    }
    interrupt.rethrow();
    return orRaise(std::move(t));
  }();
  auto seeds = orRaise(lgp::cli::prepareRun(cfg, table, false, false));
  const bool two_step = cfg.search.multi_output.mode == lgp::MultiOutputMode::TwoStep;
  PythonTicker ticker(progress, progress_interval);
  nlohmann::json exhaustive;
  std::unique_ptr<lgp::Search> single;
  std::unique_ptr<lgp::TwoStepSearch> stepped;
  std::vector<std::string> warnings;
  if (two_step) {
    stepped = std::make_unique<lgp::TwoStepSearch>(cfg, std::move(table));
    auto* s = stepped.get();
    py::gil_scoped_release nogil;
    s->run([&](int, const lgp::SearchProgress& p) {
      ticker.tick([&] { return p; }, false, [s] { s->requestStop(); });
    });
  } else {
    single = std::make_unique<lgp::Search>(cfg, std::move(table));
    auto* s = single.get();
    auto start = [&] {
      py::gil_scoped_release nogil;
      return lgp::cli::startSearch(*s, seeds, true);
    }();
    if (!start) valueError(start.error());
    warnings = std::move(start->not_seeded);
    exhaustive = std::move(start->exhaustive);
    auto snapshot = [s] { return s->progress(); };
    auto stop = [s] { s->requestStop(); };
    py::gil_scoped_release nogil;
    s->initialize();
    ticker.tick(snapshot, true, stop);
    while (!s->done()) {
      s->step();
      ticker.tick(snapshot, false, stop);
    }
    ticker.tick(snapshot, true, stop);
  }
  const lgp::Search& search = stepped ? stepped->result() : *single;
  nlohmann::json front;
  std::string note;
  {
    py::gil_scoped_release nogil;
    front = lgp::cli::frontJson(search, exhaustive);
    if (!front["members"].empty())
      note = lgp::cli::FrontExtras(search.config(), search.table()).addTo(front);
  }
  if (front["members"].empty()) valueError(lgp::cli::emptyFrontMessage(search));
  for (const auto& why : warnings) note += (note.empty() ? "" : "\n") + ("not seeded: " + why);
  return py::make_tuple(front.dump(), ticker.interrupted(), note);
}

// A config's problems, as `lgp run` reports them ("" when it is valid).
std::string checkConfig(const std::string& config_text, const std::string& base_dir) {
  try {
    parseConfig(config_text, base_dir);
  } catch (const py::value_error& e) {
    return e.what();
  }
  return "";
}

// Reads and checks a front file (readFrontJson): its JSON text.
std::string readFront(const std::string& path) {
  return orRaise(lgp::readFrontJson(path)).dump();
}

// The value at `path` (keys) of a front, or ValueError naming the first missing field (or the
// last one, when it is not an object or array as `want` says): a front is a file, or a
// daemon's answer, that may lack anything.
const nlohmann::json& field(const nlohmann::json& j, std::initializer_list<const char*> path,
                            bool want_array = false) {
  const nlohmann::json* v = &j;
  std::string at;
  for (const char* key : path) {
    at += std::string("/") + key;
    if (!v->is_object() || !v->contains(key)) valueError("front: " + at + ": missing");
    v = &(*v)[key];
  }
  if (want_array ? !v->is_array() : !v->is_object())
    valueError("front: " + at + ": must be " + (want_array ? "an array" : "an object"));
  return *v;
}

std::vector<std::string> names(const nlohmann::json& front, const char* key) {
  std::vector<std::string> out;
  const auto& list = field(front, {"table", key}, true);
  for (size_t i = 0; i < list.size(); ++i) {
    if (!list[i].is_string())
      valueError("front: /table/" + std::string(key) + "/" + std::to_string(i) +
                 ": must be a string");
    out.push_back(list[i].get<std::string>());
  }
  return out;
}

// The rows per interpreter block of the run the front came from, held to the bounds a run
// config has (/eval/block_size): the front is a file, and a block of 2^24 rows costs
// gigabytes to predict one row.
int frontBlockSize(const nlohmann::json& front) {
  const auto& eval = field(front, {"config", "eval"});
  // The run config's own reader says what is wrong, naming the field.
  auto cfg = lgp::parseRunConfig({{"data", {{"path", "front"}}}, {"eval", eval}}, "");
  if (!cfg) valueError("front: /config" + cfg.error());
  return cfg->eval.block_size;
}

// Member `index` of a front on the rows of X (rows x the front's inputs), [row][output]: the
// float32 interpreter (what the search scored, and what the emitted float code computes), or
// the double reference path. Target transforms are inverted, as the emitted code does.
Matrix predict(const std::string& front_text, size_t index, const Matrix& x, bool dbl) {
  const nlohmann::json front = parseText(front_text, "front");
  const auto& members = field(front, {"members"}, true);
  if (index >= members.size())
    valueError("member: index " + std::to_string(index) + " is past the front's " +
               std::to_string(members.size()) + " members");
  lgp::Table t;
  t.input_names = names(front, "inputs");
  t.output_names = names(front, "outputs");
  const int block = dbl ? 0 : frontBlockSize(front);
  const std::string at = "/members/" + std::to_string(index);
  const auto& member = members[index];
  for (const char* key : {"program", "outputs"})
    if (!member.is_object() || !member.contains(key))
      valueError("front: " + at + "/" + key + ": missing");
  if (!member["outputs"].is_array()) valueError("front: " + at + "/outputs: must be an array");
  const auto& outs = member["outputs"];
  lgp::Program p = orRaise(lgp::memberProgram(front, index));
  t.inputs = columns(x, "X", t.input_names.size());
  const size_t rows = x.shape(0);
  for (size_t i = 0; i < t.inputs.size(); ++i)
    for (size_t r = 0; r < rows; ++r)
      if (!std::isfinite(t.inputs[i][r]))
        valueError("X: row " + std::to_string(r) + ", column " + std::to_string(i) + " (" +
                   t.input_names[i] + ") is not a finite number");
  std::vector<lgp::TargetTransform> tr(t.output_names.size(), lgp::TargetTransform::None);
  for (size_t o = 0; o < tr.size() && o < outs.size(); ++o) {
    if (!outs[o].is_object() || !outs[o].contains("transform")) continue;
    const auto& name = outs[o]["transform"];
    const auto f =
        name.is_string() ? lgp::targetTransformFromString(name.get<std::string>()) : std::nullopt;
    if (!f)
      valueError("front: " + at + "/outputs/" + std::to_string(o) +
                 "/transform: not a target transform");
    tr[o] = *f;
  }
  std::vector<std::vector<double>> cols(t.output_names.size(), std::vector<double>(rows));
  if (rows == 0) return toMatrix(cols, 0);
  {
    py::gil_scoped_release nogil;
    t.outputs.assign(t.output_names.size(), std::vector<double>(rows, 0.0));
    if (dbl) {
      cols = lgp::evaluateReference(p, t);
    } else {
      lgp::Dataset ds(t, block);
      lgp::Interpreter interp(block);
      const auto f = interp.evaluate(p, ds);
      for (size_t o = 0; o < cols.size(); ++o)
        for (size_t r = 0; r < rows; ++r) cols[o][r] = f[o][r];
    }
    for (size_t o = 0; o < cols.size(); ++o)
      for (double& v : cols[o]) v = lgp::invertTransform(tr[o], v);
  }
  return toMatrix(cols, rows);
}

#ifdef LGP_HAVE_EMIT
// The code `lgp emit <source> --member index` prints with the same options (byte for byte):
// `source` is the front file's path as given there.
std::string emit(const std::string& front_text, size_t index, const std::string& lang_name,
                 const std::string& source, const std::string& name, const std::string& precision,
                 bool fast, bool pow_rewrites, bool domain_rewrites, bool exact_math, bool header,
                 bool helpers, bool measure) {
  const nlohmann::json front = parseText(front_text, "front");
  const auto lang = lgp::emit::languageFromString(lang_name);
  if (!lang)
    valueError("lang: expected " + lgp::emit::languageChoices() + " (got '" + lang_name + "')");
  const auto prec = lgp::precisionFromString(precision);
  if (!prec) valueError("precision: expected float, half or double (got '" + precision + "')");
  lgp::emit::EmitOptions eo;
  eo.function_name = name;
  eo.precision = *prec;
  eo.fast = fast;
  eo.pow_rewrites = pow_rewrites;
  eo.domain_rewrites = domain_rewrites;
  eo.exact_math = exact_math;
  eo.header = header;
  eo.helpers = helpers;
  if (auto st = eo.validate(*lang); !st) valueError(st.message());
  if (index >= front["members"].size())
    valueError("member: index " + std::to_string(index) + " is past the front's " +
               std::to_string(front["members"].size()) + " members");
  auto in = orRaise(lgp::emit::emitInputFromFront(front, index));
  eo.source = source + " member " + std::to_string(index);
  py::gil_scoped_release nogil;  // measuring compiles the code for three GPU families
  auto e = measure ? lgp::emit::emitMeasured(in, *lang, eo) : lgp::emit::emitProgram(in, *lang, eo);
  if (!e) {
    py::gil_scoped_acquire gil;
    valueError(e.error());
  }
  return e->code;
}
#endif

#ifdef LGP_HAVE_DATASETS
// A ground-truth table for a scene (JSON text), through the cache as `lgp data` does:
// (input names, output names, X, Y, meta JSON text).
py::tuple generate(const std::string& scene_text, const std::string& cache_dir, int threads) {
  namespace ds = lgp::datasets;
  auto scene = ds::parseScene(parseText(scene_text, "scene"), "scene");
  if (!scene) valueError(scene.error());
  ds::GenerateOptions opt;
  opt.threads = threads;
  GenerationInterrupt interrupt;
  opt.stop = [&interrupt] { return interrupt(); };
  lgp::Expected<ds::GeneratedTable> g = lgp::Status::error("not generated");
  std::string note;
  {
    py::gil_scoped_release nogil;
    if (cache_dir == lgp::kNoCache) {
      g = ds::generate(*scene, opt);
    } else {
      auto c = ds::generateCached(
          *scene, cache_dir.empty() ? ds::defaultCacheDir() : fs::path(cache_dir), opt);
      if (c) {
        note = c->note;
        g = std::move(c->table);
      } else {
        g = c.status();
      }
    }
  }
  interrupt.rethrow();
  if (!g) valueError("scene: " + g.error());
  const lgp::Table& t = g->table;
  return py::make_tuple(t.input_names, t.output_names, toMatrix(t.inputs, t.rows()),
                        toMatrix(t.outputs, t.rows()), t.meta.dump(), note);
}
#endif

// Every operator (lgp::allOps) as the front prints it and its value: for the Python side's
// registry checks (its SymPy translation covers every formula lgp prints).
py::list operators() {
  py::list out;
  const std::vector<std::string> in = {"x", "y", "z", "w"};
  const std::vector<lgp::Interval> domain = {
      {0.5, 1.5, false}, {0.25, 0.75, false}, {-1, 1, false}, {-1, 1, false}};
  const double point[4] = {1.1, 0.6, -0.3, 0.7};
  for (const auto& info : lgp::allOps()) {
    lgp::Program p;
    lgp::Instr ins;
    ins.op = info.op;
    // (bounded by kMaxArity too: GCC 12 cannot tell that arity is, and warns)
    for (int k = 0; k < std::min(info.arity, lgp::kMaxArity); ++k)
      ins.args[k] = lgp::inputOperand(k);
    p.code = {ins};
    p.outputs = {0};
    const auto f = lgp::printFormula(lgp::formulaDag(p, 4, domain), in, {"v"});
    py::dict d;
    d["name"] = std::string(info.name);
    d["arity"] = info.arity;
    d["formula"] = f.text();
    d["value"] = lgp::evaluateReferenceRow(p, point)[0];
    d["point"] = py::make_tuple(point[0], point[1], point[2], point[3]);
    out.append(d);
  }
  return out;
}

}  // namespace

PYBIND11_MODULE(_lgp, m) {
  m.doc() = "lgp's engine (C++); use the `lgp` package, not this module";
  m.def("run", &run, py::arg("config"), py::arg("base_dir"), py::arg("X").none(true),
        py::arg("y").none(true), py::arg("sample_weight").none(true),
        py::arg("progress").none(true), py::arg("progress_interval"));
  m.def("check_config", &checkConfig, py::arg("config"), py::arg("base_dir"));
  m.def("operators", &operators);
  m.def("read_front", &readFront, py::arg("path"));
  m.def("predict", &predict, py::arg("front"), py::arg("member"), py::arg("X"),
        py::arg("double_precision"));
#ifdef LGP_HAVE_EMIT
  m.def("emit", &emit, py::arg("front"), py::arg("member"), py::arg("lang"), py::arg("source"),
        py::arg("name"), py::arg("precision"), py::arg("fast"), py::arg("pow_rewrites"),
        py::arg("domain_rewrites"), py::arg("exact_math"), py::arg("header"), py::arg("helpers"),
        py::arg("measure"));
#endif
#ifdef LGP_HAVE_DATASETS
  m.def("generate", &generate, py::arg("scene"), py::arg("cache_dir"), py::arg("threads"));
#endif
  // The languages Member.emit writes (lgp::emit::allLanguages): (name, title) pairs.
  py::list languages;
#ifdef LGP_HAVE_EMIT
  for (const auto& l : lgp::emit::allLanguages())
    languages.append(py::make_tuple(std::string(l.name), std::string(l.title)));
#endif
  m.attr("languages") = py::tuple(languages);
  m.attr("has_emit") =
#ifdef LGP_HAVE_EMIT
      true;
#else
      false;
#endif
  m.attr("has_datasets") =
#ifdef LGP_HAVE_DATASETS
      true;
#else
      false;
#endif
}
