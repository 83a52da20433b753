// Step planner: exact step counts, symmetry, peak rate and duration against the
// closed-form trapezoid (host/tsa_bench/motion/trapezoid.py), over many combinations.
#include <math.h>
#include <stdio.h>

#include "board.h"
#include "planner.h"
#include "test_runner.h"

namespace {

const uint32_t MAX_STEPS = 400000;
uint32_t g_intervals[MAX_STEPS];

struct Stats {
    uint32_t count;
    double total_s;
    uint32_t min_ticks;
    uint32_t max_asym_ticks;
};

Stats plan(uint32_t steps, uint32_t rate, uint32_t accel) {
    fw::StepPlanner p;
    p.begin(steps, rate, accel);
    Stats s = {0, 0.0, 0xFFFFFFFFUL, 0};
    uint64_t ticks = 0;
    while (!p.finished() && s.count < MAX_STEPS) {
        uint32_t iv = p.next_interval();
        g_intervals[s.count++] = iv;
        ticks += iv;
        if (iv < s.min_ticks) s.min_ticks = iv;
    }
    for (uint32_t i = 0; i < s.count / 2; ++i) {
        uint32_t a = g_intervals[i], b = g_intervals[s.count - 1 - i];
        uint32_t d = a > b ? a - b : b - a;
        if (d > s.max_asym_ticks) s.max_asym_ticks = d;
    }
    s.total_s = static_cast<double>(ticks) / fw::STEP_TICK_HZ;
    return s;
}

// Closed-form trapezoid duration, as tsa_bench.motion.trapezoid.TrapezoidProfile.
double closed_form_s(double d, double rate, double accel) {
    if (d == 0) return 0;
    double v = fmin(rate, sqrt(d * accel));
    double ta = v / accel;
    double tc = fmax(0.0, (d - v * v / accel) / v);
    return 2 * ta + tc;
}

const uint32_t RATES[] = {1, 7, 100, 1000, 3200, 10667, 16000};
const uint32_t ACCELS[] = {1, 13, 1000, 32000, 160000, 320000};
const uint32_t DISTANCES[] = {1, 2, 3, 4, 5, 8, 9, 10, 17, 64, 100, 1000, 3200, 12345, 64000};

}  // namespace

TEST(core_planner_zero_steps) {
    fw::StepPlanner p;
    p.begin(0, 1000, 1000);
    CHECK(p.finished());
    CHECK_EQ(p.next_interval(), 0);
}

TEST(core_planner_exact_counts_symmetry_rate_duration) {
    double worst_err = 0, worst_rate = 0;
    uint32_t worst_asym = 0;
    for (unsigned r = 0; r < sizeof RATES / sizeof RATES[0]; ++r) {
        for (unsigned a = 0; a < sizeof ACCELS / sizeof ACCELS[0]; ++a) {
            for (unsigned d = 0; d < sizeof DISTANCES / sizeof DISTANCES[0]; ++d) {
                uint32_t steps = DISTANCES[d], rate = RATES[r], accel = ACCELS[a];
                Stats s = plan(steps, rate, accel);
                CHECK_EQ(s.count, steps);
                double expect = closed_form_s(steps, rate, accel);
                double err = fabs(s.total_s - expect) / expect;
                // The brief asks for 2 %; the method gives < 0.1 %, checked at 0.5 %.
                if (err > 0.005) testing::note("d=%u rate=%u accel=%u: %.6f s vs %.6f s", steps, rate, accel,
                                              s.total_s, expect);
                CHECK(err <= 0.005);
                if (err > worst_err) worst_err = err;
                double peak = fw::STEP_TICK_HZ / static_cast<double>(s.min_ticks);
                if (peak / rate > worst_rate) worst_rate = peak / rate;
                if (peak > rate * 1.01) testing::note("d=%u rate=%u accel=%u: peak %.1f", steps, rate, accel, peak);
                CHECK(peak <= rate * 1.01);
                if (s.max_asym_ticks > worst_asym) worst_asym = s.max_asym_ticks;
                CHECK(s.max_asym_ticks <= 1);
            }
        }
    }
    printf("planner: worst duration error %.4f %%, worst peak/rate %.5f, worst asymmetry %u tick\n",
           worst_err * 100, worst_rate, worst_asym);
}

TEST(core_planner_full_range_moves) {
    // The longest possible move (MIN to MAX twist) at bench limits and at a crawl.
    const uint32_t steps = 352000;
    Stats s = plan(steps, 16000, 320000);
    CHECK_EQ(s.count, steps);
    CHECK(fabs(s.total_s - closed_form_s(steps, 16000, 320000)) / closed_form_s(steps, 16000, 320000) < 0.001);
    CHECK_EQ(s.min_ticks, 125);
    s = plan(steps, 16000, 1);  // triangular, 1186 s long
    CHECK_EQ(s.count, steps);
    CHECK(fabs(s.total_s - closed_form_s(steps, 16000, 1)) / closed_form_s(steps, 16000, 1) < 0.002);
    CHECK(s.max_asym_ticks <= 1);
}

TEST(core_planner_single_step_is_exact_triangle) {
    for (unsigned a = 0; a < sizeof ACCELS / sizeof ACCELS[0]; ++a) {
        Stats s = plan(1, 16000, ACCELS[a]);
        double expect = closed_form_s(1, 16000, ACCELS[a]);
        CHECK_EQ(s.count, 1);
        CHECK(fabs(s.total_s - expect) / expect < 0.005);
    }
}

TEST(core_planner_short_moves_are_triangular) {
    // 200 steps at 3200 steps/s^2 cannot reach 10000 steps/s (needs 15625 steps):
    // speed rises to the middle and falls after it, never cruising.
    Stats s = plan(200, 10000, 3200);
    CHECK_EQ(s.count, 200);
    for (uint32_t i = 1; i < 100; ++i) CHECK(g_intervals[i] <= g_intervals[i - 1]);
    for (uint32_t i = 101; i < 200; ++i) CHECK(g_intervals[i] >= g_intervals[i - 1]);
    CHECK(s.min_ticks > fw::STEP_TICK_HZ / 10000 + 1);
    // A long move cruises at exactly the rate.
    s = plan(20000, 3200, 32000);
    CHECK_EQ(g_intervals[10000], fw::STEP_TICK_HZ / 3200);
}

TEST(core_planner_ramp_matches_constant_acceleration) {
    // Step n of a ramp lands at t = sqrt(2 n / a): check the first 2000 steps.
    const uint32_t accel = 1000;
    plan(10000, 16000, accel);
    uint64_t ticks = 0;
    double worst = 0;
    for (uint32_t n = 1; n <= 2000; ++n) {
        ticks += g_intervals[n - 1];
        double t = static_cast<double>(ticks) / fw::STEP_TICK_HZ;
        double exact = sqrt(2.0 * n / accel);
        double err = fabs(t - exact) / exact;
        if (err > worst) worst = err;
    }
    CHECK(worst < 0.001);
    printf("planner: worst ramp step-time error %.5f %% (a=%u, 2000 steps)\n", worst * 100, accel);
}

TEST(core_planner_stop_decelerates_at_the_limit_never_faster) {
    fw::StepPlanner p;
    p.begin(200000, 16000, 32000);
    uint32_t last = 0;
    for (int i = 0; i < 20000; ++i) last = p.next_interval();  // cruising
    p.rewind(50);  // the step generator dropped 50 queued steps
    CHECK_EQ(p.remaining(), 200000 - 20000 + 50);
    const uint32_t kept = p.interval_q8(20000 - 50 - 1) >> 8;
    CHECK_EQ(kept, last);  // cruise
    const uint32_t n = p.stop(320000);
    CHECK_EQ(n, 400u);  // 16000^2 / (2 * 320000)
    CHECK_EQ(p.remaining(), n);
    uint32_t prev = kept;
    uint64_t ticks = 0;
    uint32_t count = 0;
    while (!p.finished()) {
        const uint32_t iv = p.next_interval();
        CHECK(iv + 1 >= prev);  // never faster than the step before
        prev = iv;
        ticks += iv;
        ++count;
    }
    CHECK_EQ(count, n);
    // v / a = 50 ms at constant deceleration
    const double t = static_cast<double>(ticks) / fw::STEP_TICK_HZ;
    CHECK(t > 0.049 && t < 0.052);
    // near the end the planned deceleration is shorter: the move finishes as planned
    fw::StepPlanner q;
    q.begin(1000, 16000, 320000);
    for (int i = 0; i < 900; ++i) q.next_interval();
    CHECK_EQ(q.stop(320000), 100u);
}

// The step generator gets runs (cruise as up to 255 steps per entry, ramp groups on
// a chord) and carries the fraction of a tick itself: expanded, the runs must stay
// within a tick or so of next_interval()'s exact steps, step by step and in total.
TEST(core_planner_runs_expand_to_nearly_the_same_steps) {
    const uint32_t cases[][3] = {{64000, 16000, 320000}, {1001, 7777, 12345}, {3, 100, 50},
                                 {200000, 16000, 32000}, {999, 16000, 320000}, {1, 1, 1},
                                 {20001, 16000, 1000}, {5000, 300, 1}};
    for (unsigned c = 0; c < sizeof cases / sizeof cases[0]; ++c) {
        fw::StepPlanner a, b;
        a.begin(cases[c][0], cases[c][1], cases[c][2]);
        b.begin(cases[c][0], cases[c][1], cases[c][2]);
        uint32_t entries = 0, steps = 0;
        uint64_t t_exact = 0, t_runs = 0;
        int64_t worst_step = 0, worst_lag = 0;
        uint8_t carry = 0;
        while (!b.finished()) {
            uint32_t q8 = 0;
            int16_t add = 0;
            const uint8_t n = b.next_run(q8, add, 255);
            CHECK(n >= 1);
            ++entries;
            for (uint8_t i = 0; i < n; ++i) {
                const uint32_t sum = q8 + carry;
                carry = static_cast<uint8_t>(sum & 0xFF);
                q8 += add;
                const uint32_t exact = a.next_interval();
                t_exact += exact;
                t_runs += sum >> 8;
                const int64_t d = static_cast<int64_t>(sum >> 8) - exact;
                // 4e-4 of the interval plus rounding (each side carries its own fraction)
                if ((d < 0 ? -d : d) > static_cast<int64_t>(exact / 2500 + 2)) {
                    if (worst_step < 5) printf("case %u step %u: %lld vs exact %u\n", c, steps, static_cast<long long>(d), exact);
                    ++worst_step;
                }
                const int64_t lag = static_cast<int64_t>(t_runs) - static_cast<int64_t>(t_exact);
                if ((lag < 0 ? -lag : lag) > worst_lag) worst_lag = lag < 0 ? -lag : lag;
                ++steps;
            }
        }
        CHECK(a.finished());
        CHECK_EQ(steps, cases[c][0]);
        CHECK_EQ(worst_step, 0);
        // each edge within 0.02 % of the move's time (or 2 ticks) of where the exact plan puts it
        CHECK(worst_lag <= static_cast<int64_t>(t_exact / 5000 + 2));
        if (c == 0) CHECK(entries < 600);  // 2 x 400 ramp steps + 63,200 cruise steps in runs
        if (c == 3) printf("planner: runs for 200000 steps at 16000/s, 32000/s^2: %u entries, worst edge lag %lld ticks\n",
                           entries, static_cast<long long>(worst_lag));
    }
    // a stop after a rewind: the same number of steps, nearly the same times
    fw::StepPlanner a, b;
    a.begin(200000, 16000, 32000);
    b.begin(200000, 16000, 32000);
    for (int i = 0; i < 20000; ++i) a.next_interval();
    uint32_t done = 0, q8 = 0;
    int16_t add = 0;
    while (done < 20000) done += b.next_run(q8, add, static_cast<uint8_t>(20000 - done < 255 ? 20000 - done : 255));
    a.rewind(50);
    b.rewind(50);
    CHECK_EQ(a.stop(320000), b.stop(320000));
    uint64_t ta = 0, tb = 0;
    uint8_t carry = 0;
    while (!b.finished()) {
        const uint8_t n = b.next_run(q8, add, 255);
        for (uint8_t i = 0; i < n; ++i) {
            const uint32_t sum = q8 + carry;
            carry = static_cast<uint8_t>(sum & 0xFF);
            q8 += add;
            tb += sum >> 8;
            ta += a.next_interval();
        }
    }
    CHECK(a.finished());
    CHECK(tb >= ta && tb - ta <= ta / 2000 + 2);
}
