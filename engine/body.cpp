#include "engine/body.hpp"

#include <stdexcept>
#include <string>

namespace incise::engine {

namespace {

const Body& copyable(const Body& body) {
  if (body.gpu)
    throw std::runtime_error("body '" + (body.model ? body.model->name : std::string("?")) +
                             "': a body stepped on the GPU (solver.backend \"gpu\") cannot be copied: its step "
                             "keeps a GPU context and buffers of its own");
  if (body.cut && !body.data.efg)
    throw std::logic_error("body '" + (body.model ? body.model->name : std::string("?")) +
                           "': a cut with no EFG model to copy it for");
  return body;
}

}  // namespace

// Every member is copied here: a member added to Body must be added to this list.
Body::Body(const Body& other)
    : model(copyable(other).model),
      data(other.data),
      cut_model(other.cut_model),
      cut(other.cut ? std::make_unique<physics::CutData>(*other.cut, *data.efg) : nullptr),
      executor(other.executor ? std::make_unique<ThreadPoolExecutor>(other.executor->thread_count(),
                                                                     other.executor->has_side_helper())
                              : nullptr),
      build_ms(other.build_ms) {
  // The copied model still borrows the original's threads: it takes this body's instead.
  if (data.efg && other.executor && &other.data.efg->executor() == other.executor.get())
    data.efg->set_executor(executor.get());
}

Body& Body::operator=(const Body& other) {
  if (this != &other) *this = Body(other);
  return *this;
}

}  // namespace incise::engine
