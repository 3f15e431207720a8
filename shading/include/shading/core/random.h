// Seeded random numbers that give the same stream on every platform and compiler (the
// distributions of <random> are implementation-defined): tables, the transport Monte Carlo and
// the simulated measurements draw from these, so a seed names one result everywhere.
#pragma once

#include <cstdint>

namespace shading {

// splitmix64 (Steele, Lea & Flood 2014): advances `state` by the golden-ratio increment and
// returns a bijective mix of it.
inline std::uint64_t splitmix64(std::uint64_t& state) {
    std::uint64_t z = (state += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

// A double in [0, 1) from the top 53 bits of `bits`.
inline double uniform_double(std::uint64_t bits) { return double(bits >> 11) * 0x1.0p-53; }

// splitmix64 as a generator.
struct SplitMix64 {
    std::uint64_t state;
    std::uint64_t next() { return splitmix64(state); }
    double uniform() { return uniform_double(next()); }  // [0, 1)
};

}  // namespace shading
