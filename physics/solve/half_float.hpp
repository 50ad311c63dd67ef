// IEEE half precision (binary16) for the V-cycle's smoother copy of a large stiffness
// (paired_blocks.hpp): 2 bytes an entry where the products are bound by memory. Conversions in
// round-to-nearest-even, the F16C instructions where the CPU has them and portable code with
// the same bits elsewhere.
#pragma once

#include <cstddef>
#include <cstdint>

namespace incise::physics {

// Nearest half, ties to even: subnormal halves below 2^-14, infinity from 65520 up, NaN kept.
std::uint16_t float_to_half(float value);
// Exact.
float half_to_float(std::uint16_t half);
// out[i] = float_to_half(in[i]), i < count (F16C 8 at a time where the CPU has it).
void floats_to_halves(const float* in, std::uint16_t* out, std::size_t count);
// Whether floats_to_halves and the half products use F16C on this CPU (tests force the portable
// code through set_block_product_vectorised).
bool half_conversion_vectorised();

}  // namespace incise::physics
