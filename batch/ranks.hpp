// The processes a batch is spread over: mpirun's ranks when incise is built with MPI and
// started by mpirun, otherwise this process alone. MPI is joined only by `incise batch` and
// only under a launcher, so every other command, and a batch run by hand or by Slurm's array,
// never initialises it.
#pragma once

namespace incise::batch {

class Ranks {
 public:
  Ranks();  // joins mpirun's ranks when there are any (ranks_mpi.cpp), else rank 0 of 1
  ~Ranks();
  Ranks(const Ranks&) = delete;
  Ranks& operator=(const Ranks&) = delete;

  int rank() const { return rank_; }
  int size() const { return size_; }
  void barrier();
  // Ends every rank: one rank's error would otherwise leave the others waiting at a barrier.
  [[noreturn]] void abort(int code);

  static bool built_with_mpi();

 private:
  int rank_ = 0, size_ = 1;
  bool joined_ = false;
};

}  // namespace incise::batch
