// splitmix64's finaliser (Steele, Lea and Flood 2014): a bijective 64-bit mix whose output
// bits each depend on every input bit. For content hashes (the front's vertex identity) and
// for fixed pseudo-random offsets that must come out the same at every call (the cut face's
// lattice jitter).
#pragma once

#include <cstdint>

namespace incise::physics {

inline std::uint64_t mix64(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

}  // namespace incise::physics
