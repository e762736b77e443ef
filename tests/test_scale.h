// How much of a randomized sweep a test runs. Under the sanitizers (scripts/test's second pass,
// ASAN + UBSAN, 5-10x slower) the heaviest sweeps run fewer trials: that pass looks for memory
// errors and undefined behaviour, which a few trials' code paths show as well as all of them; the
// Release pass runs every trial. A test scales its thresholds with its trial count.
#pragma once

namespace ig::test {

#ifdef IG_TEST_SANITIZED
inline constexpr bool kSanitized = true;
#else
inline constexpr bool kSanitized = false;
#endif

// `full` trials in Release, `sanitized` under the sanitizers.
constexpr int trials(int full, int sanitized) { return kSanitized ? sanitized : full; }

}  // namespace ig::test
