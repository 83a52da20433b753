// Minimal native test runner (no dependencies). A test is a function registered with
// TEST(name); CHECK(cond) records a failure with file:line and continues; the runner
// prints one line per failing check and ends with the summary line
// "N passed, N failed" that CI reads. Exit status is non-zero when any test failed.
#pragma once
#include <stdint.h>
#include <stdio.h>

namespace testing {

typedef void (*TestFn)();

struct Registration {
    Registration(const char* name, TestFn fn);
};

// Records a failed check in the current test.
void fail(const char* file, int line, const char* expr);
// Formatted detail for the next failure message (printf-style), optional.
void note(const char* fmt, ...);

}  // namespace testing

#define TEST(name)                                                             \
    static void test_##name();                                                 \
    static testing::Registration registration_##name(#name, test_##name);     \
    static void test_##name()

#define CHECK(cond)                                                            \
    do {                                                                       \
        if (!(cond)) testing::fail(__FILE__, __LINE__, #cond);                 \
    } while (0)

#define CHECK_EQ(a, b)                                                         \
    do {                                                                       \
        long long va_ = (long long)(a), vb_ = (long long)(b);                  \
        if (va_ != vb_) {                                                      \
            testing::note("%lld != %lld", va_, vb_);                           \
            testing::fail(__FILE__, __LINE__, #a " == " #b);                   \
        }                                                                      \
    } while (0)
