#include "tests/bench/accuracy.hpp"
namespace incise::bench { int run_accuracy_bench(bool, const std::filesystem::path&, std::ostream&) { return 1; } }
