/* A minimal test harness: CHECK* record failures with file:line and go on; TEST_MAIN runs the
 * listed test functions and exits 1 if any check failed. */
#ifndef AGRIHIL_CHECK_H
#define AGRIHIL_CHECK_H

#include <math.h>
#include <stdio.h>

static int check_failures = 0;
static int check_count = 0;

#define CHECK(cond)                                                                           \
    do {                                                                                      \
        check_count++;                                                                        \
        if (!(cond)) {                                                                        \
            check_failures++;                                                                 \
            fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, __LINE__, #cond);          \
        }                                                                                     \
    } while (0)

#define CHECK_NEAR(actual, expected, tol)                                                     \
    do {                                                                                      \
        double check_a_ = (double)(actual), check_e_ = (double)(expected);                    \
        check_count++;                                                                        \
        if (!(fabs(check_a_ - check_e_) <= (tol))) {                                          \
            check_failures++;                                                                 \
            fprintf(stderr, "%s:%d: %s = %.17g, expected %.17g (tol %g)\n", __FILE__,         \
                    __LINE__, #actual, check_a_, check_e_, (double)(tol));                    \
        }                                                                                     \
    } while (0)

#define CHECK_INT(actual, expected)                                                           \
    do {                                                                                      \
        long long check_a_ = (long long)(actual), check_e_ = (long long)(expected);           \
        check_count++;                                                                        \
        if (check_a_ != check_e_) {                                                           \
            check_failures++;                                                                 \
            fprintf(stderr, "%s:%d: %s = %lld, expected %lld\n", __FILE__, __LINE__, #actual, \
                    check_a_, check_e_);                                                      \
        }                                                                                     \
    } while (0)

typedef void (*test_fn)(void);

static int run_tests(const char *suite, const test_fn *tests, const char *const *names, int n)
{
    for (int i = 0; i < n; i++) {
        int before = check_failures;
        tests[i]();
        printf("%s %s.%s\n", check_failures == before ? "ok  " : "FAIL", suite, names[i]);
    }
    printf("%s: %d checks, %d failed\n", suite, check_count, check_failures);
    return check_failures == 0 ? 0 : 1;
}

#define TEST_MAIN(suite, ...)                                                                 \
    int main(void)                                                                            \
    {                                                                                         \
        static const test_fn tests[] = {__VA_ARGS__};                                         \
        static const char names_text[] = #__VA_ARGS__;                                        \
        static char buf[sizeof names_text];                                                   \
        const char *names[sizeof tests / sizeof tests[0]];                                    \
        int n = (int)(sizeof tests / sizeof tests[0]);                                        \
        /* split "a, b, c" into names */                                                      \
        int k = 0;                                                                            \
        size_t j = 0;                                                                         \
        names[0] = buf;                                                                       \
        for (size_t i = 0; names_text[i] != '\0'; i++) {                                      \
            if (names_text[i] == ',') {                                                       \
                buf[j++] = '\0';                                                              \
                if (k + 1 < n) {                                                              \
                    names[++k] = buf + j;                                                     \
                }                                                                             \
            } else if (names_text[i] != ' ') {                                                \
                buf[j++] = names_text[i];                                                     \
            }                                                                                 \
        }                                                                                     \
        buf[j] = '\0';                                                                        \
        return run_tests(suite, tests, names, n);                                             \
    }

#endif
