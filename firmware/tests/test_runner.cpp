#include "test_runner.h"

#include <stdarg.h>
#include <string.h>

namespace testing {
namespace {

struct Entry {
    const char* name;
    TestFn fn;
};

const int MAX_TESTS = 1024;
Entry g_tests[MAX_TESTS];
int g_count = 0;
int g_current_failures = 0;
const char* g_current = "";
char g_note[256] = "";

}  // namespace

Registration::Registration(const char* name, TestFn fn) {
    if (g_count < MAX_TESTS) g_tests[g_count++] = Entry{name, fn};
}

void note(const char* fmt, ...) {
    va_list args;
    va_start(args, fmt);
    vsnprintf(g_note, sizeof g_note, fmt, args);
    va_end(args);
}

void fail(const char* file, int line, const char* expr) {
    ++g_current_failures;
    printf("FAIL %s: %s:%d: %s%s%s\n", g_current, file, line, expr, g_note[0] ? "  -- " : "", g_note);
    g_note[0] = 0;
}

}  // namespace testing

int main(int argc, char** argv) {
    using namespace testing;
    const char* filter = argc > 1 ? argv[1] : nullptr;
    int passed = 0, failed = 0;
    for (int i = 0; i < g_count; ++i) {
        if (filter && !strstr(g_tests[i].name, filter)) continue;
        g_current = g_tests[i].name;
        g_current_failures = 0;
        g_tests[i].fn();
        if (g_current_failures) {
            ++failed;
        } else {
            ++passed;
        }
    }
    printf("%d passed, %d failed\n", passed, failed);
    return failed ? 1 : 0;
}
