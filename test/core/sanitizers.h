// Whether the tests run under AddressSanitizer (scripts/test --sanitize): there the figures
// are not the point (memory and undefined behaviour are) and every step costs about five
// times as much, so the longest runs take a subset of their cases.
#pragma once

#if defined(__SANITIZE_ADDRESS__)
#define MECHANISM_SIM_TEST_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define MECHANISM_SIM_TEST_ASAN 1
#endif
#endif

namespace mechanism_sim {
namespace test_util {
#ifdef MECHANISM_SIM_TEST_ASAN
constexpr bool kSanitized = true;
#else
constexpr bool kSanitized = false;
#endif
}  // namespace test_util
}  // namespace mechanism_sim
