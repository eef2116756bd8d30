// The search: NSGA-II over (error, cost, discontinuity) on K islands, with one bounded Pareto
// archive, derivative-based (Levenberg-Marquardt) and derivative-free (Nelder-Mead, DE)
// constant refinement.
//
// One generation (step()):
//   1. Each island breeds its share of the N offspring: binary tournaments on (rank,
//      crowding), two-segment crossover and micro/macro mutation. Offspring i of generation g
//      draws from an RNG seeded with hash(seed, g, i), so variation is independent of thread
//      scheduling. A stagnant island (islands.restart_after) breeds random programs and archive
//      members instead.
//   2. Offspring are scored in parallel (OpenMP over programs, one Scorer per thread). A
//      program whose effective form was scored before takes its objectives from the semantic
//      cache (semantic_cache.hpp), which changes time, never the result.
//   3. A share of offspring gets its constants fitted (Levenberg-Marquardt with exact
//      Jacobians, then a quick Nelder-Mead polish where that did not help): this is what lets
//      a right structure with wrong constants survive.
//   4. Per island, parents + offspring are ranked (duplicates of an objective vector go last)
//      and the best by (rank, crowding) survive (elitism).
//   5. Offspring enter the archive. Every islands.migration_interval generations each island
//      sends first-front members to the next (migration.hpp); every `archive_period`
//      generations up to `archive_max` archive members not yet fully refined (in storage
//      order, or the most accurate first: refine.archive_order) get the full refinement and rejoin
//      the islands, each one island (islands.deal).
// Budgets: generations, evaluations (refinement evaluations included; an LM Jacobian pass
// over n constants counts 1 + n, see ConstantFitResult), wall time, or a stop request
// (Ctrl-C); the check happens between generations.
//
// Determinism: with the same config, seed and thread count (and no wall-time budget) the
// front is identical; in fact every per-program computation is sequential, so it is identical
// for any thread count. checkpoint()/restore() capture everything needed to continue a run
// so that the resumed run produces the same front as an uninterrupted one.
#pragma once

#include <atomic>
#include <chrono>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lgp/config/config.hpp"
#include "lgp/core/cancellation.hpp"
#include "lgp/core/program.hpp"
#include "lgp/core/rng.hpp"
#include "lgp/core/snap.hpp"
#include "lgp/core/table.hpp"
#include "lgp/eval/discontinuity.hpp"
#include "lgp/eval/fidelity.hpp"
#include "lgp/eval/interpreter.hpp"
#include "lgp/eval/objectives.hpp"
#include "lgp/search/front_gain.hpp"
#include "lgp/search/levenberg_marquardt.hpp"
#include "lgp/search/migration.hpp"
#include "lgp/search/pareto.hpp"
#include "lgp/search/semantic_cache.hpp"

namespace lgp {

// What constant refinement did in this process (not checkpointed): LM fits run, those whose
// result the scorer took, those that converged without improving, and the Nelder-Mead (and
// DE) runs with their evaluations.
struct RefineStats {
  uint64_t lm_fits = 0, lm_accepted = 0, lm_converged = 0, lm_evaluations = 0;
  uint64_t nm_runs = 0, nm_evaluations = 0;
  // Semantic cache hits (search.semantic_cache): offspring scores taken from it, and
  // offspring LM fits replayed from it (not counted in lm_fits and the other LM counters,
  // which count fits run).
  uint64_t cache_score_hits = 0, cache_lm_replays = 0;
  // Programs found to fit through float32 rounding (eval/fidelity.hpp): scores refused on the
  // sampled rows, and archive candidates refused on every row.
  uint64_t fidelity_rejects = 0, fidelity_archive_rejects = 0;
};

struct SearchProgress {
  int generation = 0;
  uint64_t evaluations = 0;
  double elapsed_s = 0;
  double evals_per_s = 0;
  size_t front_size = 0;
  double best_error = 0;                                // lowest finite error in the archive
  std::vector<std::pair<double, double>> best_at_cost;  // (cost level, best error at <= level)
  bool finished = false;
  std::string stop_reason;       // "generations", "evaluations", "wall_time", "stopped"
  int islands = 1;               // islands in use
  uint64_t migrants = 0;         // members sent between islands so far
  uint64_t restarts = 0;         // island restarts after stagnation so far
  int ranks = 1;                 // MPI ranks the islands are spread over (1 = one process)
  int threads = 1;               // OpenMP threads (per rank)
  uint64_t remote_migrants = 0;  // of `migrants`, those sent to an island on another rank
  // Offspring each of this process's islands breeds in the next generation (they follow the
  // front's gains under search.islands.adaptive, else the population's split).
  std::vector<int> island_offspring;
  // Measured cost in the archive (Search::setCostMeasure): candidates measured, and the wall
  // time the measurements took.
  uint64_t cost_measurements = 0;
  double cost_measure_s = 0;
};

// Fills front_size, best_error and best_at_cost of `p` from archive members (levels empty =
// four automatic levels spread over the members' costs).
void summarizeArchive(SearchProgress& p, const std::vector<ArchiveMember>& members,
                      const std::vector<double>& levels);

// A front member with everything the outputs need.
struct FrontEntry {
  Program program;                         // introns pruned
  Objectives obj;                          // as searched (float32 interpreter)
  std::vector<OutputMetrics> metrics;      // float32 interpreter, per output
  std::vector<OutputMetrics> metrics_ref;  // double reference evaluator, per output
  // Per error channel (objectives.channels; empty when the config has none).
  std::vector<OutputMetrics> channel_metrics, channel_metrics_ref;
  std::array<double, kNumCostTargets> cost_by_target{};
  std::vector<std::string> infix;  // per output, standalone (printOutputs on the domain)
  std::string formula;             // the whole program (programFormula on the domain)
  Cancellation cancellation;       // bits lost (cancellation.hpp)
};

class Search {
 public:
  Search(RunConfig cfg, Table table);
  ~Search();
  Search(const Search&) = delete;
  Search& operator=(const Search&) = delete;

  // The number of islands a config asks for, as the search uses it (at most population / 4).
  static int islandCount(const RunConfig& cfg);
  // An MPI run raises the island count to its rank count; a resume (on other ranks, or in one
  // process) takes that count from the checkpoint when the config's is smaller. True if it did.
  static bool adoptCheckpointIslands(RunConfig& cfg, const nlohmann::json& checkpoint);
  // Runs only islands [first, first + count) of a search of `total` islands (one MPI rank's
  // share); offspring and RNG streams keep their global indices. Before initialize()/restore().
  void setIslandRange(int first, int count, int total);
  // Replaces the in-process transport (e.g. by MPI). Before initialize()/restore().
  void setTransport(std::unique_ptr<MigrationTransport> transport);
  // Ranks this search is part of, for progress(); set by the MPI driver.
  void setRanks(int ranks) { ranks_ = ranks; }
  // The stop reason progress() reports from now on; the search is done (used for the
  // assembled result of a distributed run).
  void setStopReason(const std::string& reason) { adopted_stop_ = reason; }

  // Measured cost in the archive (objectives.measured_cost.in_search; the frontends own the
  // GPU backend and pass emit/gpu_cost.hpp's measurement here). `measure` returns the measured
  // cost of a member's final program (introns pruned, linear scaling applied), or nullopt
  // where it failed (the model's cost is kept then). Archive members carry the measured cost,
  // so the front is non-dominated in it; islands keep selecting on the model. A candidate is
  // measured only if the archive would take it at its `predictor` cost minus `slack` (the
  // predictor's worst error), so the many offspring the archive rejects on error anyway are
  // never compiled. Measurements are not checkpointed: a resume measures again (cached).
  using CostMeasure = std::function<std::optional<double>(const Program&)>;
  void setCostMeasure(CostMeasure measure, CostModel predictor, double slack);

  // Programs to start from (e.g. parsed published formulas), before initialize(): each is
  // fitted to the run's shape (fitToShape) and replaces one random initial program. Programs
  // that cannot fit are skipped; the result says why, one line per skipped program.
  std::vector<std::string> addSeeds(const std::vector<NamedProgram>& seeds);
  // Random initial population (generation 0), plus the seeds. Called by step() if needed.
  void initialize();
  // Makes this search's archive the given programs, scored on its table (used to assemble the
  // result of a multi-step run), with the given counters for progress(); no further steps.
  void adopt(const std::vector<Program>& programs, int generations, uint64_t evaluations,
             double elapsed_s, const std::string& stop_reason);
  // One generation. No-op once done(), unless check_budget is false (the MPI driver's sync
  // mode: every rank has agreed to run this generation, and one that skipped it would leave
  // its neighbours waiting for its migrants).
  void step(bool check_budget = true);
  bool done() const;
  // Thread-safe; the run stops after the current generation.
  void requestStop() { stop_.store(true); }

  // Runs to a budget, calling on_progress every progress_interval_s (and at the end).
  void run(const std::function<void(const SearchProgress&)>& on_progress = {});

  SearchProgress progress() const;
  RefineStats refineStats() const;
  // The archive's non-dominated members, sorted by cost then error, with full metrics. The
  // post-run pass: unless setSnapTwins(false), the snapped twin of every member (snap.hpp,
  // then simplified on the table's domain and relinearised) goes to a copy of the archive
  // first: it replaces its original when it is no worse in cost and discontinuity and its
  // error is higher by float32 rounding at most (float32ErrorFloor), and is otherwise offered
  // like any candidate, so a twin that is not dominated joins the front. The archive itself
  // (and so checkpoints and resumes) is left as it was.
  std::vector<FrontEntry> front() const;
  void setSnapTwins(bool on, SnapOptions o = {}) {
    snap_twins_ = on;
    snap_ = o;
  }
  // What the structured accurate end did at the start (search/structured.hpp): fits built,
  // finite, taken by the archive, placed in islands, and seconds; null when it did not run
  // (off, or a resumed search).
  const nlohmann::json& structuredInfo() const { return structured_info_; }
  // Per residual stage (search.stages): its base (formula of the member it corrects), mode,
  // picks so far and composites the archive took; null when the run has none.
  nlohmann::json stagesInfo() const;
  // The archive as it stands (unsorted, programs as searched).
  const std::vector<ArchiveMember>& archiveMembers() const { return archive_.members(); }

  // Full state (config digest, population, archive, counters). restore() rejects a checkpoint
  // from a different config or table.
  // With an island range set, the checkpoint holds this range's islands and the local
  // archive ("island_first", "island_total" say which).
  nlohmann::json checkpoint() const;
  // A checkpoint of the whole search, or of exactly this search's island range. With an
  // island range set, a whole-search checkpoint gives this range's islands and the whole
  // archive; take_counters = false starts the evaluation, migrant and restart counters at 0
  // (so that the ranks of a redistributed run do not count them N times).
  // The JSON itself, and combining the checkpoints of island ranges: io/checkpoint.hpp.
  Status restore(const nlohmann::json& state, bool take_counters = true);

  const RunConfig& config() const { return cfg_; }
  const Table& table() const { return table_; }
  const ProgramShape& shape() const { return shape_; }
  int threads() const { return threads_; }
  // The most threads a search uses: the cores this process may run on. search.threads above
  // it (or 0, "all") is capped to it.
  static int maxThreads();

 private:
  // The checkpoint JSON (io/checkpoint.hpp) reads and restores the private state.
  friend nlohmann::json checkpointToJson(const Search& s);
  friend Status restoreFromCheckpoint(Search& s, const nlohmann::json& state, bool take_counters);
  struct Island;
  friend nlohmann::json islandToJson(const Island& isl);
  friend Status islandFromJson(const nlohmann::json& ji, const ProgramShape& shape, Scorer& scorer,
                               const std::string& at, Island& isl);

  struct Individual {
    Program program;
    Objectives obj;
    bool refined = false;  // fully refined (archive-level Nelder-Mead)
  };
  // One deme: an NSGA-II population with its ranks and crowding distances.
  struct Island {
    std::vector<Individual> pop;
    std::vector<int> rank;
    std::vector<double> crowd;
    double best = std::numeric_limits<double>::infinity();  // lowest error seen here
    int stagnant = 0;   // generations since `best` last improved
    double credit = 0;  // recent front gain of its offspring (search.islands.adaptive)
  };
  // The structured fits of the table, in the run's shape, scored and offered to the archive;
  // returned in order of cost, the ones no other fit dominates.
  std::vector<Individual> structuredStart();
  // A residual stage (search/stage.hpp): the base it corrects, its residual table and the
  // island that searches the correction (programs of `shape`: the run's inputs, then the
  // base's outputs).
  struct Stage {
    Program base;  // the base's final program; empty until the first pick
    StageMode mode = StageMode::Add;
    int input = 0;  // inside: the input whose argument the correction corrects
    double base_error = 0;
    Table table;
    std::unique_ptr<Dataset> ds;
    ErrorConfig err;
    CostModel cost;
    DiscontinuityModel disc;
    ProgramShape shape;
    double error_scale = 1;  // stage error -> the composite's (mul: the weights' sums)
    std::vector<std::unique_ptr<Scorer>> scorers;  // per thread
    std::vector<std::unique_ptr<ConstantFitter>> fitters;
    Island isl;
    int since = 0;            // generations since the pick
    int picks = 0;            // picks so far
    uint64_t composites = 0;  // composites the archive took
  };
  void stepStages(int generation);
  // A new base for stage `k` from the archive (search.stages.bases, modes); false if no member
  // leaves room for a correction.
  bool pickBase(int k, Stage& st);
  // The stage's residual table, scorers and shape for its base and mode.
  void bindStage(Stage& st);
  Scorer& stageScorer(Stage& st, int thread);
  Objectives stageScore(Stage& st, int thread, const Program& p);
  // Scores (and, where picked, fits the constants of) stage programs; returns evaluations.
  uint64_t evaluateStage(Stage& st, std::vector<Individual>& inds,
                         const std::vector<uint8_t>& refine);
  // Offers the composites of `inds` (scored stage programs) to the archive.
  void offerComposites(Stage& st, const std::vector<Individual>& inds);
  // Individual i draws its refinement stream from global index index_base + i.
  void evaluateAll(std::vector<Individual>& inds, const std::vector<uint8_t>& refine,
                   uint64_t stream, uint64_t index_base = 0);
  Objectives score(Scorer& s, const Program& p) const;
  // The objectives of `p` under a scorer and the cost and discontinuity models of its table
  // (the run's, or a stage's): with linear scaling the exported mad is costed too.
  static Objectives scoreWith(Scorer& s, const Program& p, const CostModel& cost,
                              const DiscontinuityModel& disc, bool linear_scaling, int genes,
                              double extra_cost);
  // Fits the constants of one individual with thread `thread`'s scorer and fitter.
  // `key` (offspring only, with the cache on): the program's cache key, under which its LM fit
  // is recorded; `known`: what the cache held under it when the offspring was scored, whose LM
  // outcome, if any, is replayed instead of fitting.
  void refineOne(int thread, Individual& ind, uint64_t seed, uint64_t& evals, bool full,
                 const ProgramKey* key = nullptr, const SemanticCache::Entry* known = nullptr);
  // Replaces the island's population by the best `keep` of pool (NSGA-II elitism, with
  // search.cost_strata the best of each cost slice first).
  // `global`: the island's global index (its profile's cost_strata).
  void survive(int global, Island& isl, std::vector<Individual>& pool, int keep) const;
  void surviveStrata(int strata, Island& isl, std::vector<Individual>& pool, int keep) const;
  static void rankIsland(Island& isl);
  int tournament(int global, const Island& isl, Rng& rng) const;
  int tournamentBias(double error_bias, const Island& isl, Rng& rng) const;
  int islandSize(int k) const;  // population share of global island k
  // What global island k's variation may build (search.islands.profiles), and its weight
  // rate, error bias and cost strata.
  const ProgramShape& islandShape(int k) const;
  const IslandProfile* islandProfile(int k) const;  // nullptr: no profiles
  double islandWeightRate(int k) const;
  double islandErrorBias(int k) const;
  int islandCostStrata(int k) const;
  int localPopulation() const;  // offspring per generation of this search's islands
  int offspringBase() const;    // global index of this search's first offspring
  void migrate(int generation);
  void refineArchive();
  // archive_.insert, with the measured cost where setCostMeasure was called; true if the
  // archive took it, with the objectives it holds in `stored`.
  bool archiveInsert(const Program& p, const Objectives& o, bool refined,
                     Objectives* stored = nullptr);
  // Offspring per local island this generation (search.islands.adaptive); an island that
  // restarts (restart[k]) breeds its whole population.
  std::vector<int> offspringPerIsland(const std::vector<uint8_t>& restart = {}) const;
  double elapsed() const;
  std::string stopReason() const;
  Scorer& scorer(int thread);
  ConstantFitter& fitter(int thread);
  // LM on p's constants with thread `thread`'s fitter (through the exported program where the
  // output layer has several genes).
  ConstantFitResult fitConstants(int thread, Program& p, const LevenbergMarquardtConfig& lm);
  int genes() const { return err_cfg_.genes; }
  // A Scorer for work outside the per-thread ones (front assembly), with its own fidelity
  // check on the sampled rows.
  struct CheckedScorer {
    FidelityCheck check;
    Scorer scorer;
    CheckedScorer(const Search& s);
  };
  // Whether the archive candidate `p` passes the fidelity rule on every row, and its emitted
  // formula computes what it computes (formulaReproduces).
  bool fidelityOnEveryRow(const Program& p);
  // Whether the formula of `final_program` (simplified on the table's domain, as emitted)
  // reproduces its float32 values within the fidelity tolerances on every row.
  bool formulaReproduces(const Program& final_program) const;
  // The program a member stands for: introns pruned, linear scaling materialised.
  Program finalProgram(Scorer& s, const Program& p) const;

  RunConfig cfg_;
  Table table_;
  ProgramShape shape_;
  ErrorConfig err_cfg_;
  CostModel cost_;
  DiscontinuityModel disc_;
  double transform_cost_ = 0;
  Dataset ds_;
  int threads_ = 1;

  std::vector<std::unique_ptr<Scorer>> scorers_;        // one per OpenMP thread
  std::vector<std::unique_ptr<FidelityCheck>> checks_;  // theirs, on the sampled rows
  std::unique_ptr<FidelityCheck> full_check_;           // every row (archive candidates)
  std::vector<double> fidelity_tol_;                    // fidelityTolerances(table_)
  uint64_t fidelity_archive_rejects_ = 0;
  std::vector<std::unique_ptr<ConstantFitter>> fitters_;
  std::vector<Island> islands_;
  std::vector<ProgramShape> profile_shapes_;  // per entry of search.islands.profiles
  std::vector<int> targets_;  // migrationTargets of the whole search (set with island_total_)
  std::unique_ptr<MigrationTransport> transport_;
  int island_first_ = 0;  // global index of islands_[0]
  int island_total_ = 0;  // islands of the whole search; 0 = not yet known (all are local)
  bool range_set_ = false;
  int ranks_ = 1;
  uint64_t remote_migrants_before_ = 0;
  uint64_t restarts_ = 0;
  uint64_t migrants_before_ = 0;  // migrants of earlier sessions (restored checkpoints)
  Archive archive_;
  FrontGain front_gain_;  // what each generation's offspring add to the front, per island
  int generation_ = 0;
  bool initialized_ = false;
  uint64_t evaluations_ = 0;
  double elapsed_before_ = 0;  // from restored checkpoints
  std::chrono::steady_clock::time_point start_;
  std::atomic<bool> stop_{false};
  // RefineStats, counted by every thread.
  std::atomic<uint64_t> lm_fits_{0}, lm_accepted_{0}, lm_converged_{0}, lm_evaluations_{0};
  std::atomic<uint64_t> nm_runs_{0}, nm_evaluations_{0};
  std::unique_ptr<SemanticCache> cache_;
  uint64_t cache_score_hits_ = 0;
  std::atomic<uint64_t> cache_lm_replays_{0};
  // LM fits the error the scorer measures (lm_metric configured, or plain least squares on
  // rmse of one channel; not a transformed output under linear scaling, whose scale LM and the
  // scorer fit on different scales): where LM has converged, Nelder-Mead has nothing to add.
  bool lm_fits_the_error_ = false;
  uint64_t session_evals_ = 0;  // evaluations since construction/restore (for evals/s)
  std::vector<Program> seeds_;
  nlohmann::json structured_info_;
  std::vector<std::unique_ptr<Stage>> stages_;
  std::string adopted_stop_;      // set by adopt()
  std::vector<Interval> domain_;  // the table's (tableDomain)
  bool snap_twins_ = true;
  SnapOptions snap_;
  CostMeasure measure_;
  CostModel measure_predictor_;
  double measure_slack_ = 0;
  uint64_t measurements_ = 0;
  double measure_s_ = 0;
  // The snapped and simplified twin of an archive program, if it differs and fits the shape.
  std::optional<Program> snappedTwin(Scorer& s, const Program& p) const;
};

// A copy of `p` that satisfies `shape`: constants padded with zeros to the shape's count and,
// in OutputMode::Last, outputs moved to the last opcodes when nothing later reads them. Errors
// say why it cannot fit (too long, too many constants, an operator the run does not allow).
Expected<Program> fitToShape(const Program& p, const ProgramShape& shape);

}  // namespace lgp
