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
  MpiTransport(Comm& comm, std::vector<int> owner, bool sync, ProgramShape shape)
      : comm_(comm),
        owner_(std::move(owner)),
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
    const int total = static_cast<int>(owner_.size());
    const int from = (to - 1 + total) % total;  // the ring: migrationTarget(from) == to
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
  std::vector<int> owner_;  // island -> rank
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

Expected<DistributedResult> runDistributed(RunConfig cfg, const Table& table,
                                           DistributedOptions opt) {
  const auto started = Clock::now();
  Comm comm;
  const int rank = comm.rank(), ranks = comm.size();
  const bool sync = cfg.mpi.migration == MigrationMode::Sync;
  auto warn = [&](const std::string& w) {
    if (rank == 0 && opt.on_warning) opt.on_warning(w);
  };

  // A resume starts from rank 0's file (the other ranks may be on machines that do not see
  // its file system).
  json resume_state;
  if (opt.resume) {
    std::string bytes;
    Status read = Status::ok();
    if (rank == 0) {
      auto ck = readCheckpointFile(opt.checkpoint_path);
      if (ck) {
        const auto v = json::to_msgpack(*ck);
        bytes.assign(v.begin(), v.end());
      } else {
        read = ck.status();
      }
    }
    if (auto s = comm.agree(read); !s) return s;
    comm.broadcast(bytes, 0);
    resume_state = json::from_msgpack(bytes);
    if (Search::adoptCheckpointIslands(cfg, resume_state))
      warn("search.islands.count: " + std::to_string(cfg.search.islands.count) +
           " islands, as in the checkpoint");
  }

  // Every rank runs at least one island.
  int total = Search::islandCount(cfg);
  Status setup = Status::ok();
  if (total < ranks) {
    if (cfg.search.population / 4 < ranks) {
      setup =
          Status::error("/search/population: " + std::to_string(ranks) + " ranks need at least " +
                        std::to_string(4 * ranks) + " individuals (one island of 4 per rank; got " +
                        std::to_string(cfg.search.population) + ")");
    } else {
      warn("search.islands.count is " + std::to_string(cfg.search.islands.count) + ": using " +
           std::to_string(ranks) + " islands, one per rank");
      cfg.search.islands.count = ranks;
      total = ranks;
    }
  }
  if (cfg.search.threads == 0) cfg.search.threads = threadsPerRank(comm.handle());
  if (auto s = comm.agree(setup); !s) return s;
  if (cfg.mpi.np > 0 && cfg.mpi.np != ranks)
    warn("mpi.np is " + std::to_string(cfg.mpi.np) + ", the launcher started " +
         std::to_string(ranks) + " ranks; running on " + std::to_string(ranks));

  std::vector<int> owner(total);
  for (int r = 0; r < ranks; ++r)
    for (int k = r * total / ranks; k < (r + 1) * total / ranks; ++k) owner[k] = r;
  const int first = rank * total / ranks;
  const int count = (rank + 1) * total / ranks - first;

  auto search = std::make_unique<Search>(cfg, table);
  search->setIslandRange(first, count, total);
  search->setRanks(ranks);
  auto transport = std::make_unique<MpiTransport>(comm, owner, sync, search->shape());
  MpiTransport* mig = transport.get();
  search->setTransport(std::move(transport));

  // Start: from the checkpoint, or from random programs plus seeds.
  Status start = Status::ok();
  if (opt.resume) {
    try {
      const json& ck = resume_state;
      const auto& parts = ck.value("parts", json::array());
      // Sync mode needs every rank at the same generation (migration rounds are matched by
      // order); the parts of an async checkpoint may be a generation or two apart.
      bool same_generation = true;
      for (const auto& p : parts)
        same_generation =
            same_generation && p.value("generation", -1) == ck.value("generation", -2);
      if (static_cast<int>(parts.size()) == ranks && ck.value("island_total", 0) == total &&
          parts[rank].value("island_first", -1) == first && (!sync || same_generation)) {
        start = search->restore(parts[rank]);  // the same layout: each rank exactly
      } else {
        // Another rank count: islands dealt anew, every rank starts from the whole archive,
        // and rank 0 carries the counters.
        start = search->restore(ck, rank == 0);
      }
    } catch (const json::exception& e) {
      start = Status::error(std::string("checkpoint: ") + e.what());
    }
    if (!start && rank == 0) start = Status::error(opt.checkpoint_path + ": " + start.message());
  } else {
    const auto skipped = search->addSeeds(opt.seeds);
    for (const auto& why : skipped) warn("/search/seed_references: not seeded: " + why);
    search->initialize();
  }
  if (auto s = comm.agree(start); !s) return s;
  if (opt.on_search) opt.on_search(search.get());

  // Rank 0's view of the others.
  std::vector<Report> reports(ranks);
  std::map<int, std::vector<json>> parts;  // checkpoint round -> state per rank
  std::vector<json> finals(ranks), stats(ranks);
  std::vector<std::string> own_reasons(ranks);  // why each rank stopped on its own ("" = told)
  std::string global_reason;                    // set when rank 0 stops everyone
  bool told_to_stop = false, stop_sent = false;
  int checkpoint_seq = 0, answered_seq = 0, wanted_seq = 0;

  auto writeCheckpoint = [&](const std::vector<json>& states) {
    auto combined = combineCheckpoints(cfg, search->shape(), states);
    if (!combined) {
      warn("checkpoint not written: " + combined.error());
      return;
    }
    if (auto s = writeCheckpointFile(*combined, opt.checkpoint_path); !s)
      warn("checkpoint not written: " + s.message());
  };
  auto handle = [&](Message& m) {
    switch (m.tag) {
      case kMigrants:
        mig->deliver(m);
        break;
      case kReport: {
        Report& r = reports[m.source];
        r.generation = m.body.at("generation").get<int>();
        r.evaluations = m.body.at("evaluations").get<uint64_t>();
        r.migrants = m.body.at("migrants").get<uint64_t>();
        r.remote_migrants = m.body.at("remote_migrants").get<uint64_t>();
        r.restarts = m.body.at("restarts").get<uint64_t>();
        r.evals_per_s = m.body.at("evals_per_s").get<double>();
        r.received = Clock::now();
        r.front.clear();
        for (const auto& o : m.body.at("front")) r.front.push_back(objFromJson(o));
        break;
      }
      case kControl:
        if (m.body.contains("stop")) {
          told_to_stop = true;
          search->requestStop();
        }
        if (m.body.contains("checkpoint")) wanted_seq = m.body.at("checkpoint").get<int>();
        break;
      case kPart: {
        auto& round = parts[m.body.at("seq").get<int>()];
        round.resize(ranks);
        round[m.source] = std::move(m.body.at("state"));
        break;
      }
      case kFinal:
        finals[m.source] = std::move(m.body.at("state"));
        stats[m.source] = std::move(m.body.at("stats"));
        own_reasons[m.source] = m.body.at("reason").get<std::string>();
        break;
      default:
        break;
    }
  };
  // Sync mode keeps migrant batches for the transport's ordered receives.
  auto pump = [&]() {
    for (int tag : {kReport, kControl, kPart, kFinal, kMigrants}) {
      if (sync && tag == kMigrants) continue;
      while (auto m = comm.poll(tag)) handle(*m);
    }
    comm.reap();
  };
  auto mergedProgress = [&]() {
    SearchProgress p = search->progress();
    Archive merged(cfg.search.archive);
    for (const auto& m : search->archiveMembers()) merged.insert(m.program, m.obj);
    const Program none;
    for (int r = 1; r < ranks; ++r) {
      p.evaluations += reports[r].evaluations;
      p.migrants += reports[r].migrants;
      p.remote_migrants += reports[r].remote_migrants;
      p.restarts += reports[r].restarts;
      p.evals_per_s += reports[r].evals_per_s;
      for (const auto& o : reports[r].front) merged.insert(none, o);
    }
    summarizeArchive(p, merged.members(), cfg.output.progress_cost_levels);
    p.islands = total;
    p.ranks = ranks;
    return p;
  };

  const double report_every = std::clamp(cfg.output.progress_interval_s, 0.1, 1.0);
  auto last_report = Clock::now(), last_progress = Clock::now(), last_checkpoint = Clock::now();
  const bool checkpoints = !opt.checkpoint_path.empty();
  while (true) {
    pump();
    const bool done = search->done();
    bool stop = false, checkpoint_now = false;
    if (sync) {
      // One collective per generation: whether any rank is done, whether rank 0 wants a
      // checkpoint, and the evaluations so far; every rank draws the same conclusion.
      const bool due = rank == 0 && checkpoints &&
                       seconds(Clock::now() - last_checkpoint) >= opt.checkpoint_interval_s;
      uint64_t in[3] = {done ? 1u : 0u, due ? 1u : 0u, search->progress().evaluations};
      uint64_t out[3] = {0, 0, 0};
      comm.allreduceSum(in, out, 3);
      if (cfg.search.max_evaluations > 0 && out[2] >= cfg.search.max_evaluations) {
        global_reason = "evaluations";
        stop = true;
      }
      stop = stop || out[0] > 0;
      if (stop && !done) told_to_stop = true;
      checkpoint_now = out[1] > 0 && !stop;
      if (checkpoint_now) wanted_seq = ++checkpoint_seq;
    } else {
      if (rank == 0) {
        // Reports are up to report_every old: extrapolate at each rank's last rate, so the
        // evaluation budget is not overshot by a report period's worth.
        double evaluations = static_cast<double>(search->progress().evaluations);
        for (int r = 1; r < ranks; ++r)
          evaluations += static_cast<double>(reports[r].evaluations) +
                         (reports[r].evaluations > 0
                              ? reports[r].evals_per_s * seconds(Clock::now() - reports[r].received)
                              : 0.0);
        if (cfg.search.max_evaluations > 0 &&
            evaluations >= static_cast<double>(cfg.search.max_evaluations) &&
            global_reason.empty()) {
          global_reason = "evaluations";
          search->requestStop();
        }
        // A rank that stopped for any reason but its generation budget (which every rank
        // reaches by itself) stops all of them.
        std::string why = search->done() ? search->progress().stop_reason : "";
        for (int r = 1; r < ranks && why.empty(); ++r)
          if (!own_reasons[r].empty() && own_reasons[r] != "generations") why = own_reasons[r];
        if (!why.empty() && why != "generations" && !stop_sent) {
          if (!search->done()) {
            // Rank 0 stops for another rank's reason: that is the run's reason, not "stopped".
            search->requestStop();
            if (global_reason.empty()) global_reason = why;
          }
          for (int r = 1; r < ranks; ++r) comm.send(r, kControl, {{"stop", why}});
          stop_sent = true;
        }
        if (checkpoints && !search->done() &&
            seconds(Clock::now() - last_checkpoint) >= opt.checkpoint_interval_s) {
          wanted_seq = ++checkpoint_seq;
          for (int r = 1; r < ranks; ++r) comm.send(r, kControl, {{"checkpoint", wanted_seq}});
          // A rank that has finished never answers: keep only the last few open rounds.
          parts.erase(parts.begin(), parts.lower_bound(wanted_seq - 2));
        }
      }
      stop = search->done();
      checkpoint_now = !stop && wanted_seq > answered_seq;
    }
    if (checkpoint_now) {
      answered_seq = wanted_seq;
      if (rank == 0) {
        auto& round = parts[wanted_seq];
        round.resize(ranks);
        round[0] = search->checkpoint();
        last_checkpoint = Clock::now();
      } else {
        comm.send(0, kPart, {{"seq", wanted_seq}, {"state", search->checkpoint()}});
      }
    }
    if (rank == 0) {
      // Write the newest complete round; older ones are superseded.
      for (auto it = parts.rbegin(); it != parts.rend(); ++it) {
        const bool complete = std::all_of(it->second.begin(), it->second.end(),
                                          [](const json& j) { return !j.is_null(); });
        if (!complete) continue;
        writeCheckpoint(it->second);
        parts.erase(parts.begin(), it.base());
        break;
      }
    }
    if (stop) break;
    search->step(!sync);
    const auto now = Clock::now();
    if (rank != 0 && seconds(now - last_report) >= report_every) {
      json r = reportOf(*search);
      json front = json::array();
      for (const auto& m : search->archiveMembers()) front.push_back(objToJson(m.obj));
      r["front"] = std::move(front);
      comm.send(0, kReport, r);
      last_report = now;
    }
    if (rank == 0 && opt.on_progress &&
        seconds(now - last_progress) >= cfg.output.progress_interval_s) {
      opt.on_progress(mergedProgress());
      last_progress = now;
    }
  }

  // The end: every rank's final state goes to rank 0, then nothing may stay in flight.
  const std::string own = told_to_stop ? "" : search->progress().stop_reason;
  json state = search->checkpoint();
  if (opt.on_search) opt.on_search(nullptr);
  // Time in MPI calls up to here (the drain below waits for the slowest rank to finish).
  json mine = {{"rank", rank},
               {"generation", search->progress().generation},
               {"elapsed_s", seconds(Clock::now() - started)},
               {"comm_s", comm.busySeconds()},
               {"messages", comm.messagesSent()},
               {"bytes", comm.bytesSent()},
               {"migrant_batches", mig->batches()},
               {"migrant_bytes", mig->batchBytes()}};
  if (rank == 0) {
    finals[0] = std::move(state);
    own_reasons[0] = own;
    stats[0] = std::move(mine);
  } else {
    comm.send(0, kFinal, {{"state", std::move(state)}, {"reason", own}, {"stats", mine}});
  }
  comm.drain(handle);
  if (rank != 0) return DistributedResult{};

  for (int r = 0; r < ranks; ++r)
    if (finals[r].is_null())
      return Status::error("rank " + std::to_string(r) + " sent no final state");
  auto combined = combineCheckpoints(cfg, search->shape(), finals);
  if (!combined) return combined.status();
  if (checkpoints) {
    if (auto s = writeCheckpointFile(*combined, opt.checkpoint_path); !s)
      warn("final checkpoint not written: " + s.message());
  }
  std::string reason = global_reason;
  for (int r = 0; r < ranks && reason.empty(); ++r) reason = own_reasons[r];
  if (reason.empty()) reason = "stopped";
  DistributedResult out;
  out.search = std::make_unique<Search>(cfg, table);
  auto& result = out.search;
  if (auto s = result->restore(*combined); !s) return s;
  result->setRanks(ranks);
  result->setStopReason(reason);
  double comm_s = 0, elapsed_s = 0;
  for (const auto& st : stats) {
    comm_s += st.value("comm_s", 0.0);
    elapsed_s += st.value("elapsed_s", 0.0);
  }
  out.stats = {{"migration", std::string(toString(cfg.mpi.migration))},
               {"comm_share", elapsed_s > 0 ? comm_s / elapsed_s : 0.0},
               {"ranks", stats}};
  if (opt.on_progress) {
    SearchProgress p = result->progress();
    p.evals_per_s = p.elapsed_s > 0 ? static_cast<double>(p.evaluations) / p.elapsed_s : 0;
    opt.on_progress(p);
  }
  return out;
}

}  // namespace lgp::mpi
