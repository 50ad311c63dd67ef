// Runs a fuzz target's harness over the files of the folders it is given, without libFuzzer:
// the ctest fuzz_corpus_* tests replay fuzz/corpus/ (the regression inputs of every finding
// among them) in every test build, sanitizer builds included, where clang is not needed.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size);

int main(int argc, char** argv) {
  int inputs = 0;
  for (int a = 1; a < argc; ++a) {
    for (const auto& entry : std::filesystem::directory_iterator(argv[a])) {
      if (!entry.is_regular_file()) continue;
      std::ifstream in(entry.path(), std::ios::binary);
      const std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      LLVMFuzzerTestOneInput(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size());
      ++inputs;
    }
  }
  std::printf("%d inputs, each ended in a result or a refusal\n", inputs);
  return inputs > 0 ? 0 : 1;  // an empty corpus would pass vacuously
}
