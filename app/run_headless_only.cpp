// Built when INCISE_WITH_WINDOW is OFF: the command exists and says why it cannot run.
#include "app/commands.hpp"

#include <stdexcept>

namespace incise::app {

int run(const RunArgs&) {
  throw std::runtime_error("run: this build has no window (configure with -DINCISE_WITH_WINDOW=ON); "
                           "use `incise replay` for headless runs");
}

}  // namespace incise::app
