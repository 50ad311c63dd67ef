// Built without MPI: one rank.
#include "batch/ranks.hpp"

#include <cstdlib>

namespace incise::batch {

Ranks::Ranks() = default;
Ranks::~Ranks() = default;
void Ranks::barrier() {}
void Ranks::abort(int code) { std::exit(code); }
bool Ranks::built_with_mpi() { return false; }

}  // namespace incise::batch
