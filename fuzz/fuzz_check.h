// What every fuzz target uses to state an invariant: a broken one aborts, which libFuzzer reports as a
// crash with the input that broke it.
#pragma once

#include <cstdio>
#include <cstdlib>

#define REFRACT_FUZZ_CHECK(condition)                                                              \
    do {                                                                                           \
        if (!(condition)) {                                                                        \
            std::fprintf(stderr, "%s:%d: invariant broken: %s\n", __FILE__, __LINE__, #condition); \
            std::abort();                                                                          \
        }                                                                                          \
    } while (false)
