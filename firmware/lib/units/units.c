#include "units.h"

__attribute__((noinline)) uint64_t units_div_round_u64(uint64_t n, uint64_t d) { return (n + d / 2u) / d; }
