#include "lgp/search/mpi_driver.hpp"

#include <mpi.h>
#include <omp.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <limits>
#include <list>
#include <map>
#include <optional>

#include "lgp/io/checkpoint.hpp"
#include "lgp/io/result.hpp"

namespace lgp::mpi {

namespace {

using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

// Point-to-point message kinds. Every message is a MessagePack-encoded JSON value.
enum Tag : int {
  kMigrants = 11,  // a batch for one island: {"to", "m": [[program, obj], ...]}
  kReport = 12,    // rank -> 0: counters and the archive's objective vectors
  kControl = 13,   // 0 -> rank: {"stop": reason} or {"checkpoint": seq}
  kPart = 14,      // rank -> 0: {"seq", "state"} (one rank's checkpoint)
  kFinal = 15,     // rank -> 0: {"state", "reason", "own"} at the end
};

struct Message {
  int source = -1, tag = -1;
  json body;
};

double seconds(Clock::duration d) {
  return std::chrono::duration<double>(d).count();
}

json objToJson(const Objectives& o) {
  return json::array({o.finite() ? json(o.error) : json(nullptr), o.cost, o.discontinuity});
}

Objectives objFromJson(const json& j) {
  Objectives o;
  o.error = j.at(0).is_number() ? j.at(0).get<double>() : std::numeric_limits<double>::infinity();
  o.cost = j.at(1).get<double>();
  o.discontinuity = j.at(2).get<double>();
  return o;
}

// Adds the wall time of its scope to a counter (time spent in MPI calls).
class Busy {
 public:
  explicit Busy(double& total) : total_(total), start_(Clock::now()) {}
  ~Busy() { total_ += seconds(Clock::now() - start_); }
  Busy(const Busy&) = delete;
  Busy& operator=(const Busy&) = delete;

 private:
  double& total_;
  Clock::time_point start_;
};

// Point-to-point traffic with per-peer counts, so that the end of a run can receive every
// message still in flight before MPI_Finalize (see drain()). Sends are non-blocking; their
// buffers live until MPI reports them complete.
class Comm {
 public:
  Comm() {
    MPI_Comm_dup(MPI_COMM_WORLD, &comm_);
    MPI_Comm_rank(comm_, &rank_);
    MPI_Comm_size(comm_, &size_);
    sent_.assign(size_, 0);
    received_.assign(size_, 0);
  }
  ~Comm() {
    waitAll();
    MPI_Comm_free(&comm_);
  }
  Comm(const Comm&) = delete;
  Comm& operator=(const Comm&) = delete;

  int rank() const { return rank_; }
  int size() const { return size_; }
  MPI_Comm handle() const { return comm_; }

  // Returns the message's size in bytes.
  size_t send(int dst, int tag, const json& body) {
    Busy b(busy_s_);
    pending_.push_back({MPI_REQUEST_NULL, json::to_msgpack(body)});
    auto& p = pending_.back();
    MPI_Isend(p.bytes.data(), static_cast<int>(p.bytes.size()), MPI_BYTE, dst, tag, comm_,
              &p.request);
    ++sent_[dst];
    const size_t bytes = p.bytes.size();
    bytes_sent_ += bytes;
    reapNow();  // may free p, this very send's buffer, if MPI has completed it already
    return bytes;
  }

  // The next message with this tag from any rank, if one has arrived.
  std::optional<Message> poll(int tag) {
    Busy b(busy_s_);
    int flag = 0;
    MPI_Status st;
    MPI_Iprobe(MPI_ANY_SOURCE, tag, comm_, &flag, &st);
    if (!flag) return std::nullopt;
    return receive(st);
  }

  // Waits for the next message with this tag from `src` (any tag: MPI_ANY_TAG).
  Message wait(int src, int tag) {
    Busy b(busy_s_);
    MPI_Status st;
    MPI_Probe(src, tag, comm_, &st);
    return receive(st);
  }

  // Frees the buffers of completed sends.
  void reap() {
    Busy b(busy_s_);
    reapNow();
  }

  // One collective of the per-generation agreement (sync mode).
  void allreduceSum(const uint64_t* in, uint64_t* out, int n) {
    Busy b(busy_s_);
    MPI_Allreduce(in, out, n, MPI_UINT64_T, MPI_SUM, comm_);
  }

  double busySeconds() const { return busy_s_; }
  uint64_t messagesSent() const {
    uint64_t n = 0;
    for (uint64_t c : sent_) n += c;
    return n;
  }
  uint64_t bytesSent() const { return bytes_sent_; }

  void reapNow() {
    for (auto it = pending_.begin(); it != pending_.end();) {
      int done = 0;
      MPI_Test(&it->request, &done, MPI_STATUS_IGNORE);
      it = done ? pending_.erase(it) : std::next(it);
    }
  }

  // Collective, once every rank has sent its last message: tells each rank how many messages
  // it was sent, receives the ones not yet taken (handing each to `handle`), and completes
  // every send. Afterwards nothing is in flight.
  void drain(const std::function<void(Message&)>& handle) {
    Busy b(busy_s_);
    std::vector<uint64_t> expected(size_, 0);
    MPI_Alltoall(sent_.data(), 1, MPI_UINT64_T, expected.data(), 1, MPI_UINT64_T, comm_);
    for (int src = 0; src < size_; ++src)
      while (received_[src] < expected[src]) {
        Message m = wait(src, MPI_ANY_TAG);
        handle(m);
      }
    waitAll();
  }

  // Every rank's flag and message; all ranks return the same status (the lowest failing
  // rank's message).
  Status agree(const Status& local) {
    const int mine = local ? size_ : rank_;
    int first = size_;
    MPI_Allreduce(&mine, &first, 1, MPI_INT, MPI_MIN, comm_);
    if (first == size_) return Status::ok();
    std::string msg = local ? std::string() : local.message();
    broadcast(msg, first);
    return Status::error(first == 0 ? msg : "rank " + std::to_string(first) + ": " + msg);
  }

  void broadcast(std::string& bytes, int root) {
    uint64_t n = bytes.size();
    MPI_Bcast(&n, 1, MPI_UINT64_T, root, comm_);
    bytes.resize(n);
    // Chunks below INT_MAX bytes: MPI counts are ints.
    for (uint64_t off = 0; off < n; off += 1u << 30) {
      const int len = static_cast<int>(std::min<uint64_t>(n - off, 1u << 30));
      MPI_Bcast(bytes.data() + off, len, MPI_BYTE, root, comm_);
    }
  }

 private:
  struct Pending {
    MPI_Request request;
    std::vector<uint8_t> bytes;
  };
  Message receive(const MPI_Status& st) {
    int n = 0;
    MPI_Get_count(&st, MPI_BYTE, &n);
    std::vector<uint8_t> bytes(static_cast<size_t>(n));
    MPI_Recv(bytes.data(), n, MPI_BYTE, st.MPI_SOURCE, st.MPI_TAG, comm_, MPI_STATUS_IGNORE);
    ++received_[st.MPI_SOURCE];
    Message m;
    m.source = st.MPI_SOURCE;
    m.tag = st.MPI_TAG;
    m.body = json::from_msgpack(bytes);
    return m;
  }
  void waitAll() {
    for (auto& p : pending_) MPI_Wait(&p.request, MPI_STATUS_IGNORE);
    pending_.clear();
  }

  MPI_Comm comm_ = MPI_COMM_NULL;
  int rank_ = 0, size_ = 1;
  std::vector<uint64_t> sent_, received_;
  std::list<Pending> pending_;
  double busy_s_ = 0;
  uint64_t bytes_sent_ = 0;
};

// Migration over MPI: batches for islands on this rank stay in memory, the others become one
// message each.
class MpiTransport final : public MigrationTransport {
 public:
  MpiTransport(Comm& comm, std::vector<int> owner, std::vector<int> sources, bool sync,
               ProgramShape shape)
      : comm_(comm),
        owner_(std::move(owner)),
        sources_(std::move(sources)),
        sync_(sync),
        shape_(std::move(shape)),
        inbox_(owner_.size()),
        arrived_(owner_.size(), 0) {}

  void send(int /*from*/, int to, std::vector<Migrant> migrants) override {
    sent_ += migrants.size();
    if (owner_[to] == comm_.rank()) {
      auto& box = inbox_[to];
      box.insert(box.end(), std::make_move_iterator(migrants.begin()),
                 std::make_move_iterator(migrants.end()));
      return;
    }
    remote_ += migrants.size();
    json m = json::array();
    for (const auto& g : migrants) m.push_back({toJson(g.program), objToJson(g.obj)});
    batch_bytes_ += comm_.send(owner_[to], kMigrants, {{"to", to}, {"m", std::move(m)}});
    ++batches_;
  }

  std::vector<Migrant> receive(int to) override {
    const int from = sources_[to];  // migrationTargets(...)[from] == to
    if (sync_ && owner_[from] != comm_.rank()) {
      // This round's batch from the neighbour; batches for this rank's other islands that
      // come first (same sender, same order of sending) are kept for their turn.
      while (!arrived_[to]) {
        Message m = comm_.wait(owner_[from], kMigrants);
        deliver(m);
      }
    } else if (!sync_) {
      while (auto m = comm_.poll(kMigrants)) deliver(*m);
    }
    arrived_[to] = 0;
    std::vector<Migrant> out;
    out.swap(inbox_[to]);
    return out;
  }

  void deliver(const Message& m) {
    const int to = m.body.at("to").get<int>();
    if (to < 0 || to >= static_cast<int>(owner_.size()) || owner_[to] != comm_.rank()) return;
    for (const auto& g : m.body.at("m")) {
      auto p = programFromJson(g.at(0), shape_);
      if (p) inbox_[to].push_back({std::move(*p), objFromJson(g.at(1))});
    }
    arrived_[to] = 1;
  }

  uint64_t sent() const override { return sent_; }
  uint64_t sentRemote() const override { return remote_; }
  uint64_t batches() const { return batches_; }
  uint64_t batchBytes() const { return batch_bytes_; }

 private:
  Comm& comm_;
  std::vector<int> owner_;    // island -> rank
  std::vector<int> sources_;  // island -> the island it receives from
  bool sync_;
  ProgramShape shape_;
  std::vector<std::vector<Migrant>> inbox_;
  std::vector<uint8_t> arrived_;  // sync: this round's batch is in the inbox
  uint64_t sent_ = 0, remote_ = 0, batches_ = 0, batch_bytes_ = 0;
};

// What rank 0 knows of another rank between reports.
struct Report {
  int generation = 0;
  uint64_t evaluations = 0, migrants = 0, remote_migrants = 0, restarts = 0;
  double evals_per_s = 0;
  Clock::time_point received;
  std::vector<Objectives> front;
};

json reportOf(const Search& s) {
  const auto p = s.progress();
  return {{"generation", p.generation}, {"evaluations", p.evaluations},
          {"migrants", p.migrants},     {"remote_migrants", p.remote_migrants},
          {"restarts", p.restarts},     {"evals_per_s", p.evals_per_s}};
}

// OpenMP threads for one rank when the config says "all cores": the cores this process may
// run on, shared with the other ranks on the node unless the launcher bound it to fewer.
int threadsPerRank(MPI_Comm comm) {
  if (std::getenv("OMP_NUM_THREADS") != nullptr) return omp_get_max_threads();
  MPI_Comm node;
  MPI_Comm_split_type(comm, MPI_COMM_TYPE_SHARED, 0, MPI_INFO_NULL, &node);
  int local = 1;
  MPI_Comm_size(node, &local);
  MPI_Comm_free(&node);
  const int procs = omp_get_num_procs();  // honours the affinity mask
  const int cores = static_cast<int>(std::max(1L, sysconf(_SC_NPROCESSORS_ONLN)));
  return procs < cores ? std::max(1, procs) : std::max(1, cores / local);
}

}  // namespace

Session::Session(int* argc, char*** argv) {
  int provided = 0;
  MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided);
  MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
  MPI_Comm_size(MPI_COMM_WORLD, &size_);
}

Session::~Session() {
  MPI_Finalize();
}

Expected<std::string> shareBytes(const Expected<std::string>& on_rank0) {
  Comm comm;
  const Status root = comm.rank() != 0 ? Status::ok() : on_rank0 ? Status::ok() : on_rank0.status();
  if (auto s = comm.agree(root); !s) return s;
  std::string bytes = comm.rank() == 0 ? *on_rank0 : std::string();
  comm.broadcast(bytes, 0);
  return bytes;
}

Expected<Table> shareTable(const Expected<Table>& on_rank0) {
  Comm comm;
  const Status root = comm.rank() != 0 ? Status::ok() : on_rank0 ? Status::ok() : on_rank0.status();
  if (auto s = comm.agree(root); !s) return s;
  std::string bytes;
  if (comm.rank() == 0) {
    const Table& t = *on_rank0;
    const auto v = json::to_msgpack(json{{"input_names", t.input_names},
                                         {"output_names", t.output_names},
                                         {"inputs", t.inputs},
                                         {"outputs", t.outputs},
                                         {"weights", t.weights},
                                         {"meta", t.meta}});
    bytes.assign(v.begin(), v.end());
  }
  comm.broadcast(bytes, 0);
  if (comm.rank() == 0) return *on_rank0;
  const json j = json::from_msgpack(bytes);
  Table t;
  j.at("input_names").get_to(t.input_names);
  j.at("output_names").get_to(t.output_names);
  j.at("inputs").get_to(t.inputs);
  j.at("outputs").get_to(t.outputs);
  j.at("weights").get_to(t.weights);
  t.meta = j.at("meta");
  return t;
}

namespace {

// One rank's part of runDistributed. Every rank runs its islands and exchanges migrants with
// the others; rank 0 also watches the rest (their reports make the merged progress), decides
// for all of them when to stop and to checkpoint in async mode, writes the checkpoints and
// assembles the result. In sync mode one collective per generation makes those decisions.
class Driver {
 public:
  Driver(RunConfig cfg, const Table& table, DistributedOptions opt)
      : cfg_(std::move(cfg)),
        table_(table),
        opt_(std::move(opt)),
        rank_(comm_.rank()),
        ranks_(comm_.size()),
        sync_(cfg_.mpi.migration == MigrationMode::Sync),
        checkpoints_(!opt_.checkpoint_path.empty()) {}

  Expected<DistributedResult> run() {
    if (auto s = readResume(); !s) return s;
    if (auto s = layOutIslands(); !s) return s;
    if (auto s = start(); !s) return s;
    if (opt_.on_search) opt_.on_search(search_.get());
    loop();
    return finish();
  }

 private:
  void warn(const std::string& w) const {
    if (rank_ == 0 && opt_.on_warning) opt_.on_warning(w);
  }

  // A resume starts from rank 0's file (the other ranks may be on machines that do not see
  // its file system).
  Status readResume() {
    if (!opt_.resume) return Status::ok();
    std::string bytes;
    Status read = Status::ok();
    if (rank_ == 0) {
      auto ck = readCheckpointFile(opt_.checkpoint_path);
      if (ck) {
        const auto v = json::to_msgpack(*ck);
        bytes.assign(v.begin(), v.end());
      } else {
        read = ck.status();
      }
    }
    if (auto s = comm_.agree(read); !s) return s;
    comm_.broadcast(bytes, 0);
    resume_state_ = json::from_msgpack(bytes);
    if (Search::adoptCheckpointIslands(cfg_, resume_state_))
      warn("search.islands.count: " + std::to_string(cfg_.search.islands.count) +
           " islands, as in the checkpoint");
    return Status::ok();
  }

  // Every rank runs at least one island; rank r runs [first_, first_ + count_).
  Status layOutIslands() {
    total_ = Search::islandCount(cfg_);
    Status setup = Status::ok();
    if (total_ < ranks_) {
      if (cfg_.search.population / 4 < ranks_) {
        setup = Status::error("/search/population: " + std::to_string(ranks_) +
                              " ranks need at least " + std::to_string(4 * ranks_) +
                              " individuals (one island of 4 per rank; got " +
                              std::to_string(cfg_.search.population) + ")");
      } else {
        warn("search.islands.count is " + std::to_string(cfg_.search.islands.count) + ": using " +
             std::to_string(ranks_) + " islands, one per rank");
        cfg_.search.islands.count = ranks_;
        total_ = ranks_;
      }
    }
    if (cfg_.search.threads == 0) cfg_.search.threads = threadsPerRank(comm_.handle());
    if (auto s = comm_.agree(setup); !s) return s;
    if (cfg_.mpi.np > 0 && cfg_.mpi.np != ranks_)
      warn("mpi.np is " + std::to_string(cfg_.mpi.np) + ", the launcher started " +
           std::to_string(ranks_) + " ranks; running on " + std::to_string(ranks_));
    owner_.resize(total_);
    for (int r = 0; r < ranks_; ++r)
      for (int k = r * total_ / ranks_; k < (r + 1) * total_ / ranks_; ++k) owner_[k] = r;
    first_ = rank_ * total_ / ranks_;
    count_ = (rank_ + 1) * total_ / ranks_ - first_;
    return Status::ok();
  }

  // The local search: from the checkpoint, or from random programs plus seeds.
  Status start() {
    search_ = std::make_unique<Search>(cfg_, table_);
    search_->setIslandRange(first_, count_, total_);
    search_->setRanks(ranks_);
    const auto& ic = cfg_.search.islands;
    auto transport = std::make_unique<MpiTransport>(
        comm_, owner_,
        migrationSources(
            migrationTargets(static_cast<int>(owner_.size()), ic.profiles, ic.topology)),
        sync_, search_->shape());
    mig_ = transport.get();
    search_->setTransport(std::move(transport));
    Status start = Status::ok();
    if (opt_.resume) {
      start = restore();
      if (!start && rank_ == 0)
        start = Status::error(opt_.checkpoint_path + ": " + start.message());
    } else {
      const auto skipped = search_->addSeeds(opt_.seeds);
      for (const auto& why : skipped) warn("/search/seed_references: not seeded: " + why);
      search_->initialize();
    }
    return comm_.agree(start);
  }

  Status restore() {
    try {
      const json& ck = resume_state_;
      const auto& parts = ck.value("parts", json::array());
      // Sync mode needs every rank at the same generation (migration rounds are matched by
      // order); the parts of an async checkpoint may be a generation or two apart.
      bool same_generation = true;
      for (const auto& p : parts)
        same_generation =
            same_generation && p.value("generation", -1) == ck.value("generation", -2);
      if (static_cast<int>(parts.size()) == ranks_ && ck.value("island_total", 0) == total_ &&
          parts[rank_].value("island_first", -1) == first_ && (!sync_ || same_generation))
        return search_->restore(parts[rank_]);  // the same layout: each rank exactly
      // Another rank count: islands dealt anew, every rank starts from the whole archive,
      // and rank 0 carries the counters.
      return search_->restore(ck, rank_ == 0);
    } catch (const json::exception& e) {
      return Status::error(std::string("checkpoint: ") + e.what());
    }
  }

  void handle(Message& m) {
    switch (m.tag) {
      case kMigrants:
        mig_->deliver(m);
        break;
      case kReport:
        readReport(m);
        break;
      case kControl:
        if (m.body.contains("stop")) {
          told_to_stop_ = true;
          search_->requestStop();
        }
        if (m.body.contains("checkpoint")) wanted_seq_ = m.body.at("checkpoint").get<int>();
        break;
      case kPart: {
        auto& round = parts_[m.body.at("seq").get<int>()];
        round.resize(ranks_);
        round[m.source] = std::move(m.body.at("state"));
        break;
      }
      case kFinal:
        finals_[m.source] = std::move(m.body.at("state"));
        stats_[m.source] = std::move(m.body.at("stats"));
        own_reasons_[m.source] = m.body.at("reason").get<std::string>();
        break;
      default:
        break;
    }
  }

  void readReport(const Message& m) {
    Report& r = reports_[m.source];
    r.generation = m.body.at("generation").get<int>();
    r.evaluations = m.body.at("evaluations").get<uint64_t>();
    r.migrants = m.body.at("migrants").get<uint64_t>();
    r.remote_migrants = m.body.at("remote_migrants").get<uint64_t>();
    r.restarts = m.body.at("restarts").get<uint64_t>();
    r.evals_per_s = m.body.at("evals_per_s").get<double>();
    r.received = Clock::now();
    r.front.clear();
    for (const auto& o : m.body.at("front")) r.front.push_back(objFromJson(o));
  }

  // Sync mode keeps migrant batches for the transport's ordered receives.
  void pump() {
    for (int tag : {kReport, kControl, kPart, kFinal, kMigrants}) {
      if (sync_ && tag == kMigrants) continue;
      while (auto m = comm_.poll(tag)) handle(*m);
    }
    comm_.reap();
  }

  SearchProgress mergedProgress() const {
    SearchProgress p = search_->progress();
    Archive merged(cfg_.search.archive);
    for (const auto& m : search_->archiveMembers()) merged.insert(m.program, m.obj);
    const Program none;
    for (int r = 1; r < ranks_; ++r) {
      p.evaluations += reports_[r].evaluations;
      p.migrants += reports_[r].migrants;
      p.remote_migrants += reports_[r].remote_migrants;
      p.restarts += reports_[r].restarts;
      p.evals_per_s += reports_[r].evals_per_s;
      for (const auto& o : reports_[r].front) merged.insert(none, o);
    }
    summarizeArchive(p, merged.members(), cfg_.output.progress_cost_levels);
    p.islands = total_;
    p.ranks = ranks_;
    return p;
  }

  void writeCheckpoint(const std::vector<json>& states) const {
    auto combined = combineCheckpoints(cfg_, search_->shape(), states);
    if (!combined) {
      warn("checkpoint not written: " + combined.error());
      return;
    }
    if (auto s = writeCheckpointFile(*combined, opt_.checkpoint_path); !s)
      warn("checkpoint not written: " + s.message());
  }

  bool checkpointDue() const {
    return checkpoints_ && seconds(Clock::now() - last_checkpoint_) >= opt_.checkpoint_interval_s;
  }

  // Sync mode: one collective per generation says whether any rank is done, whether rank 0
  // wants a checkpoint, and the evaluations so far; every rank draws the same conclusion.
  // Returns whether to stop; sets *checkpoint_now.
  bool syncRound(bool* checkpoint_now) {
    const bool done = search_->done();
    const bool due = rank_ == 0 && checkpointDue();
    uint64_t in[3] = {done ? 1u : 0u, due ? 1u : 0u, search_->progress().evaluations};
    uint64_t out[3] = {0, 0, 0};
    comm_.allreduceSum(in, out, 3);
    bool stop = false;
    if (cfg_.search.max_evaluations > 0 && out[2] >= cfg_.search.max_evaluations) {
      global_reason_ = "evaluations";
      stop = true;
    }
    stop = stop || out[0] > 0;
    if (stop && !done) told_to_stop_ = true;
    *checkpoint_now = out[1] > 0 && !stop;
    if (*checkpoint_now) wanted_seq_ = ++checkpoint_seq_;
    return stop;
  }

  // Async mode, rank 0: the evaluation budget, a stop for every rank when one stopped for
  // its own reason, and the checkpoint rounds.
  void control() {
    // Reports are up to report_every old: extrapolate at each rank's last rate, so the
    // evaluation budget is not overshot by a report period's worth.
    double evaluations = static_cast<double>(search_->progress().evaluations);
    for (int r = 1; r < ranks_; ++r)
      evaluations += static_cast<double>(reports_[r].evaluations) +
                     (reports_[r].evaluations > 0
                          ? reports_[r].evals_per_s * seconds(Clock::now() - reports_[r].received)
                          : 0.0);
    if (cfg_.search.max_evaluations > 0 &&
        evaluations >= static_cast<double>(cfg_.search.max_evaluations) && global_reason_.empty()) {
      global_reason_ = "evaluations";
      search_->requestStop();
    }
    // A rank that stopped for any reason but its generation budget (which every rank
    // reaches by itself) stops all of them.
    std::string why = search_->done() ? search_->progress().stop_reason : "";
    for (int r = 1; r < ranks_ && why.empty(); ++r)
      if (!own_reasons_[r].empty() && own_reasons_[r] != "generations") why = own_reasons_[r];
    if (!why.empty() && why != "generations" && !stop_sent_) {
      if (!search_->done()) {
        // Rank 0 stops for another rank's reason: that is the run's reason, not "stopped".
        search_->requestStop();
        if (global_reason_.empty()) global_reason_ = why;
      }
      for (int r = 1; r < ranks_; ++r) comm_.send(r, kControl, {{"stop", why}});
      stop_sent_ = true;
    }
    if (!search_->done() && checkpointDue()) {
      wanted_seq_ = ++checkpoint_seq_;
      for (int r = 1; r < ranks_; ++r) comm_.send(r, kControl, {{"checkpoint", wanted_seq_}});
      // A rank that has finished never answers: keep only the last few open rounds.
      parts_.erase(parts_.begin(), parts_.lower_bound(wanted_seq_ - 2));
    }
  }

  // This rank's part of checkpoint round wanted_seq_; rank 0 then writes the newest complete
  // round (older ones are superseded).
  void checkpointRound(bool checkpoint_now) {
    if (checkpoint_now) {
      answered_seq_ = wanted_seq_;
      if (rank_ == 0) {
        auto& round = parts_[wanted_seq_];
        round.resize(ranks_);
        round[0] = search_->checkpoint();
        last_checkpoint_ = Clock::now();
      } else {
        comm_.send(0, kPart, {{"seq", wanted_seq_}, {"state", search_->checkpoint()}});
      }
    }
    if (rank_ != 0) return;
    for (auto it = parts_.rbegin(); it != parts_.rend(); ++it) {
      const bool complete = std::all_of(it->second.begin(), it->second.end(),
                                        [](const json& j) { return !j.is_null(); });
      if (!complete) continue;
      writeCheckpoint(it->second);
      parts_.erase(parts_.begin(), it.base());
      break;
    }
  }

  // After a generation: the other ranks report to rank 0, which reports the merged progress.
  void report() {
    const auto now = Clock::now();
    if (rank_ != 0 && seconds(now - last_report_) >= report_every_) {
      json r = reportOf(*search_);
      json front = json::array();
      for (const auto& m : search_->archiveMembers()) front.push_back(objToJson(m.obj));
      r["front"] = std::move(front);
      comm_.send(0, kReport, r);
      last_report_ = now;
    }
    if (rank_ == 0 && opt_.on_progress &&
        seconds(now - last_progress_) >= cfg_.output.progress_interval_s) {
      opt_.on_progress(mergedProgress());
      last_progress_ = now;
    }
  }

  void loop() {
    reports_.resize(ranks_);
    finals_.resize(ranks_);
    stats_.resize(ranks_);
    own_reasons_.resize(ranks_);
    report_every_ = std::clamp(cfg_.output.progress_interval_s, 0.1, 1.0);
    last_report_ = last_progress_ = last_checkpoint_ = Clock::now();
    while (true) {
      pump();
      bool stop = false, checkpoint_now = false;
      if (sync_) {
        stop = syncRound(&checkpoint_now);
      } else {
        if (rank_ == 0) control();
        stop = search_->done();
        checkpoint_now = !stop && wanted_seq_ > answered_seq_;
      }
      checkpointRound(checkpoint_now);
      if (stop) break;
      search_->step(!sync_);
      report();
    }
  }

  // The end: every rank's final state goes to rank 0, then nothing may stay in flight.
  Expected<DistributedResult> finish() {
    const std::string own = told_to_stop_ ? "" : search_->progress().stop_reason;
    json state = search_->checkpoint();
    if (opt_.on_search) opt_.on_search(nullptr);
    // Time in MPI calls up to here (the drain below waits for the slowest rank to finish).
    json mine = {{"rank", rank_},
                 {"generation", search_->progress().generation},
                 {"elapsed_s", seconds(Clock::now() - started_)},
                 {"comm_s", comm_.busySeconds()},
                 {"messages", comm_.messagesSent()},
                 {"bytes", comm_.bytesSent()},
                 {"migrant_batches", mig_->batches()},
                 {"migrant_bytes", mig_->batchBytes()}};
    if (rank_ == 0) {
      finals_[0] = std::move(state);
      own_reasons_[0] = own;
      stats_[0] = std::move(mine);
    } else {
      comm_.send(0, kFinal, {{"state", std::move(state)}, {"reason", own}, {"stats", mine}});
    }
    comm_.drain([this](Message& m) { handle(m); });
    if (rank_ != 0) return DistributedResult{};
    return assemble();
  }

  // Rank 0: the whole run's search from the final states, its reason and the MPI statistics.
  Expected<DistributedResult> assemble() {
    for (int r = 0; r < ranks_; ++r)
      if (finals_[r].is_null())
        return Status::error("rank " + std::to_string(r) + " sent no final state");
    auto combined = combineCheckpoints(cfg_, search_->shape(), finals_);
    if (!combined) return combined.status();
    if (checkpoints_) {
      if (auto s = writeCheckpointFile(*combined, opt_.checkpoint_path); !s)
        warn("final checkpoint not written: " + s.message());
    }
    std::string reason = global_reason_;
    for (int r = 0; r < ranks_ && reason.empty(); ++r) reason = own_reasons_[r];
    if (reason.empty()) reason = "stopped";
    DistributedResult out;
    out.search = std::make_unique<Search>(cfg_, table_);
    auto& result = out.search;
    if (auto s = result->restore(*combined); !s) return s;
    result->setRanks(ranks_);
    result->setStopReason(reason);
    double comm_s = 0, elapsed_s = 0;
    for (const auto& st : stats_) {
      comm_s += st.value("comm_s", 0.0);
      elapsed_s += st.value("elapsed_s", 0.0);
    }
    out.stats = {{"migration", std::string(toString(cfg_.mpi.migration))},
                 {"comm_share", elapsed_s > 0 ? comm_s / elapsed_s : 0.0},
                 {"ranks", stats_}};
    if (opt_.on_progress) {
      SearchProgress p = result->progress();
      p.evals_per_s = p.elapsed_s > 0 ? static_cast<double>(p.evaluations) / p.elapsed_s : 0;
      opt_.on_progress(p);
    }
    return out;
  }

  const Clock::time_point started_ = Clock::now();
  RunConfig cfg_;
  const Table& table_;
  DistributedOptions opt_;
  Comm comm_;
  const int rank_, ranks_;
  const bool sync_;
  const bool checkpoints_;
  json resume_state_;
  int total_ = 0, first_ = 0, count_ = 0;
  std::vector<int> owner_;  // island -> rank
  std::unique_ptr<Search> search_;
  MpiTransport* mig_ = nullptr;  // owned by search_

  // Rank 0's view of the others.
  std::vector<Report> reports_;
  std::map<int, std::vector<json>> parts_;  // checkpoint round -> state per rank
  std::vector<json> finals_, stats_;
  std::vector<std::string> own_reasons_;  // why each rank stopped on its own ("" = told)
  std::string global_reason_;             // set when rank 0 stops everyone
  bool told_to_stop_ = false, stop_sent_ = false;
  int checkpoint_seq_ = 0, answered_seq_ = 0, wanted_seq_ = 0;
  double report_every_ = 1;
  Clock::time_point last_report_, last_progress_, last_checkpoint_;
};

}  // namespace

Expected<DistributedResult> runDistributed(RunConfig cfg, const Table& table,
                                           DistributedOptions opt) {
  return Driver(std::move(cfg), table, std::move(opt)).run();
}

}  // namespace lgp::mpi
