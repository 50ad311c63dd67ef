// Built with MPI (OpenMPI): rank and size from MPI_COMM_WORLD when started by mpirun.
#include "batch/ranks.hpp"

#include <mpi.h>

#include <cstdlib>

namespace incise::batch {

namespace {

// mpirun (OpenMPI, or a PMI/PMIx launcher such as srun) says so in the environment; a process
// started otherwise stays out of MPI, which would otherwise start a singleton runtime.
bool launched_by_mpirun() {
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_SIZE"})
    if (std::getenv(name)) return true;
  return false;
}

}  // namespace

Ranks::Ranks() {
  if (!launched_by_mpirun()) return;
  MPI_Init(nullptr, nullptr);
  joined_ = true;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
  MPI_Comm_size(MPI_COMM_WORLD, &size_);
}

Ranks::~Ranks() {
  if (joined_) MPI_Finalize();
}

void Ranks::barrier() {
  if (joined_) MPI_Barrier(MPI_COMM_WORLD);
}

void Ranks::abort(int code) {
  if (joined_) MPI_Abort(MPI_COMM_WORLD, code);
  std::exit(code);
}

bool Ranks::built_with_mpi() { return true; }

}  // namespace incise::batch
