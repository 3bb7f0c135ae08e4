/*
 * ew_test.h — a tiny test harness: TEST(name){...}, CHECK*, and a main that
 * runs every registered test and prints "N passed, N failed".
 * A test may call SKIP("why") to mark itself skipped (the executable then
 * exits 77 when every test skipped, which CTest reports as skipped).
 */
#ifndef EW_TEST_H
#define EW_TEST_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef void (*ew_test_fn)(void);
typedef struct { const char *name; ew_test_fn fn; } ew_test_entry;

#define EW_MAX_TESTS 256
static ew_test_entry ew_tests_[EW_MAX_TESTS];
static int ew_ntests_;
static int ew_failed_now_;
static int ew_skipped_now_;

#define TEST(tname)                                                               \
    static void test_##tname(void);                                               \
    __attribute__((constructor)) static void reg_##tname(void) {                  \
        if (ew_ntests_ < EW_MAX_TESTS) {                                         \
            ew_tests_[ew_ntests_].name = #tname;                                  \
            ew_tests_[ew_ntests_].fn = test_##tname;                              \
            ew_ntests_++;                                                        \
        }                                                                        \
    }                                                                            \
    static void test_##tname(void)

#define FAIL_AT(...)                                                             \
    do {                                                                         \
        fprintf(stderr, "  %s:%d: ", __FILE__, __LINE__);                        \
        fprintf(stderr, __VA_ARGS__);                                            \
        fprintf(stderr, "\n");                                                   \
        ew_failed_now_ = 1;                                                      \
    } while (0)

#define CHECK(cond)                                                              \
    do { if (!(cond)) { FAIL_AT("CHECK(%s) failed", #cond); return; } } while (0)
#define CHECK_EQ_INT(a, b)                                                       \
    do { long long a_ = (long long)(a), b_ = (long long)(b);                     \
         if (a_ != b_) { FAIL_AT("%s == %lld, expected %s == %lld", #a, a_, #b, b_); return; } } while (0)
#define CHECK_NEAR(a, b, tol)                                                    \
    do { double a_ = (double)(a), b_ = (double)(b);                              \
         if (!(fabs(a_ - b_) <= (tol))) {                                        \
             FAIL_AT("%s = %.9g, expected %.9g (tol %g)", #a, a_, b_, (double)(tol)); return; } } while (0)
#define CHECK_STR_CONTAINS(hay, needle)                                          \
    do { const char *h_ = (hay); if (!h_ || !strstr(h_, (needle))) {             \
         FAIL_AT("\"%s\" does not contain \"%s\"", h_ ? h_ : "(null)", (needle)); return; } } while (0)
#define SKIP(why)                                                                \
    do { fprintf(stderr, "  skipped: %s\n", (why)); ew_skipped_now_ = 1; return; } while (0)

int main(int argc, char **argv) {
    int passed = 0, failed = 0, skipped = 0;
    const char *only = argc > 1 ? argv[1] : NULL;
    for (int i = 0; i < ew_ntests_; i++) {
        if (only && strcmp(only, ew_tests_[i].name) != 0) continue;
        ew_failed_now_ = 0;
        ew_skipped_now_ = 0;
        ew_tests_[i].fn();
        if (ew_failed_now_) { failed++; fprintf(stderr, "FAIL %s\n", ew_tests_[i].name); }
        else if (ew_skipped_now_) { skipped++; fprintf(stderr, "SKIP %s\n", ew_tests_[i].name); }
        else { passed++; fprintf(stderr, "ok   %s\n", ew_tests_[i].name); }
    }
    printf("%d passed, %d failed, %d skipped\n", passed, failed, skipped);
    if (failed) return 1;
    if (passed == 0 && skipped > 0) return 77;
    return 0;
}

#endif
