// One search over several processes and machines: the islands of a Search spread over the
// ranks of an MPI job (`mpirun -np N lgp run cfg.json`, or `srun` under SLURM).
//
// Layout. The K islands (search.islands.count, raised to N when smaller) are split into N
// consecutive ranges, one per rank; each rank runs a Search over its range with its own OpenMP
// threads and its own archive. Offspring and RNG streams keep their global indices, so a rank
// computes exactly what that share of a one-process search would, up to migration.
//
// Migration follows the ring of migration.hpp; a batch for an island on another rank is one
// MPI message. Two modes (config `mpi.migration`):
//   - "async" (default): sends never block and a rank takes whatever has arrived when it
//     migrates, so a slow rank never stalls the others. Fronts depend on timing.
//   - "sync": a rank waits for its neighbours' batches of the same round, and the ranks agree
//     on stopping every generation (one small allreduce). The same seed, ranks, threads and
//     islands give the same front.
//
// Rank 0 owns the global view: it merges the ranks' progress reports into the progress line,
// collects checkpoints (every checkpoint_interval_s it asks every rank for its state at the
// next generation boundary and writes one combined checkpoint, see combineCheckpoints in
// io/checkpoint.hpp), and at the end assembles the final archive from every rank's state, in
// rank order, for the front files. Budgets: generations per rank; evaluations
// summed over ranks (rank 0 tells the others to stop); wall time per rank; a stop request
// (signal) on any rank stops all of them.
//
// Faults. A rank that dies ends the job: the launcher (mpirun, srun) aborts the other ranks
// and says which one died. Checkpoints are written atomically by rank 0, so the last one
// survives; resuming it on N ranks restores each rank exactly ("parts"), on another N the
// islands are dealt anew and the archive goes to every rank.
#pragma once

#include <cstdlib>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "lgp/config/config.hpp"
#include "lgp/core/program.hpp"
#include "lgp/core/status.hpp"
#include "lgp/core/table.hpp"
#include "lgp/search/search.hpp"

namespace lgp::mpi {

// True when an MPI launcher started this process (Open MPI's mpirun, an MPICH/Hydra mpiexec,
// or srun with a PMI/PMIx plugin). Needs no MPI library, so a build without MPI can refuse to
// run N uncoordinated copies of one search.
inline bool launchedByLauncher() {
  for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK", "PMI_SIZE"})
    if (std::getenv(v) != nullptr) return true;
  return false;
}

// Tasks srun started for this step when it did so without a PMI plugin (then every task would
// run the whole search on its own); 0 when not under srun or when a launcher is present.
inline int slurmTasksWithoutPmi() {
  const char* n = std::getenv("SLURM_STEP_NUM_TASKS");
  if (n == nullptr || launchedByLauncher()) return 0;
  const int tasks = std::atoi(n);
  return tasks > 1 ? tasks : 0;
}

// Everything below exists only in builds with LGP_WITH_MPI (the frontends test LGP_HAVE_MPI).

// MPI_Init_thread (funneled: only the main thread talks to MPI) and MPI_Finalize.
class Session {
 public:
  Session(int* argc, char*** argv);
  ~Session();
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;
  int rank() const { return rank_; }
  int size() const { return size_; }

 private:
  int rank_ = 0, size_ = 1;
};

struct DistributedOptions {
  std::vector<NamedProgram> seeds;  // fitted to the shape by every rank (see Search::addSeeds)
  std::string checkpoint_path;      // written by rank 0; empty = no checkpoints
  double checkpoint_interval_s = 60;
  bool resume = false;  // start from checkpoint_path (read by rank 0, sent to every rank)
  // Rank 0 only, on the main thread: merged progress every output.progress_interval_s and at
  // the end; warnings (seeds that do not fit, islands raised to the rank count).
  std::function<void(const SearchProgress&)> on_progress;
  std::function<void(const std::string&)> on_warning;
  // Every rank: the local search once it exists, and nullptr before it goes away, so that a
  // signal handler can call requestStop() on it.
  std::function<void(Search*)> on_search;
};

// Collective: rank 0's bytes (or its error) on every rank, e.g. the config file's text, so
// that only rank 0 needs to see the file.
Expected<std::string> shareBytes(const Expected<std::string>& on_rank0);

// Collective: rank 0's table (or its error) on every rank, so that a scene is generated once
// and the data file need only be readable where rank 0 runs.
Expected<Table> shareTable(const Expected<Table>& on_rank0);

struct DistributedResult {
  // Rank 0: the assembled search (every island, the merged archive, counters summed over
  // ranks; done, with the run's stop reason) for front() and the front files. Else nullptr.
  std::unique_ptr<Search> search;
  // Rank 0: per rank its generation, elapsed_s, comm_s (wall time inside MPI calls, waits
  // for neighbours included), messages and bytes sent (of which migrant batches);
  // comm_share = sum comm_s / sum elapsed_s.
  nlohmann::json stats;
};

// Runs one search over every rank of MPI_COMM_WORLD; every rank calls it. An error on any
// rank before the search starts is returned on every rank.
Expected<DistributedResult> runDistributed(RunConfig cfg, const Table& table,
                                           DistributedOptions options);

}  // namespace lgp::mpi
