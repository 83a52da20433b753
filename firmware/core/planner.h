// StepPlanner: trapezoidal (or triangular) step timing for one move, in integer math,
// with no division per step.
//
// Contract: begin(steps, rate, accel) plans exactly `steps` steps; next_interval()
// returns, step by step, the time from the previous step edge (from the start, for the
// first) in STEP_TICK_HZ ticks, until finished(). rate and accel are clamped to >= 1
// (the Device validates them against cfg first). begin() costs one 32-bit square root
// and two 32-bit divisions (~0.1 ms on the AVR); next_interval() costs a few 16x16
// multiplies, table reads and shifts (no division), so the main loop keeps up with the
// step ISR at the top rate with time to spare.
//
// The step generator is fed runs (next_run): a cruise is a few entries of up to 255
// steps, a ramp beyond its first 64 steps goes out in linear groups (the interval+add
// of Klipper's step compression), so the main loop's work per step is small where
// steps are fast.
//
// Method: step i (0-based) is timed by k = min(i, steps-1-i), its distance from the
// nearer end, so the profile is symmetric by construction. On the ramps the interval is
// c0 R(k), R(k) = sqrt(k+1) - sqrt(k), c0 = f sqrt(2/a): the ramp steps then land
// exactly where constant acceleration puts them (the sum telescopes to c0 sqrt(n)).
// R(k) comes from a flash table for k < 256 and, beyond, from R(k) = 1/(2 sqrt(k+1/2))
// (relative error < 5e-7) with 1/sqrt interpolated in a 193-entry table after scaling
// by powers of 4 (error < 3e-5). The one step that crosses from ramp to cruise, and
// the middle step of an odd triangular move, get their closed-form interval, computed
// once in begin() as c0 n / (sqrt(P) + sqrt(Q)) with 32-bit square roots (no 64-bit
// arithmetic). Times carry their fraction of a tick (24.8 fixed point) from step to
// step, so rounding never accumulates.
//
// Controlled stop: after the step generator dropped `rewind` queued steps (STOP), stop()
// turns what is left into a deceleration at a_max from the speed of the last step
// kept: n = v^2 / (2 a_max) steps, never faster than that step, or, when the move
// would end sooner anyway, the rest of the move as planned. It returns the steps left.
#pragma once
#include <stdint.h>

namespace fw {

class StepPlanner {
public:
    StepPlanner();
    void begin(uint32_t steps, uint32_t rate_steps_per_s, uint32_t accel_steps_per_s2);
    void abort() { remaining_ = 0; }
    bool finished() const { return remaining_ == 0; }
    uint32_t remaining() const { return remaining_; }
    // Call only while !finished().
    uint32_t next_interval();
    // The next run of steps for the step generator: step j of the run (0-based) lasts
    // q8 + j * add, in 1/256 tick (no carry: the generator carries the fraction). Up to
    // max_count cruise steps at once (add = 0); on the ramps and while stopping, one
    // step below k = 64, beyond it groups of G <= k / 16 steps (a power of two, <= 64)
    // on the chord between the group's exact end points. Returns the count (0 when
    // finished). Expanded, the runs give next_interval()'s steps within 4e-4 of each
    // interval (a fraction of a tick at the top rate).
    uint8_t next_run(uint32_t& q8, int16_t& add, uint8_t max_count);
    // Give back the last `steps` intervals handed out (they were never executed).
    void rewind(uint32_t steps);
    // Turn the rest into a stop at a_max (see above); returns the steps left to go.
    uint32_t stop(uint32_t a_max_steps_per_s2);
    // Interval of step `index` of the planned move (before any stop), in 1/256 tick.
    uint32_t interval_q8(uint32_t index) const;

    // c0 = f sqrt(2/a) in 1/256 tick (f = STEP_TICK_HZ), for a >= 1.
    static uint32_t c0_q8(uint32_t accel_steps_per_s2);

private:
    static uint32_t ramp_q8(uint32_t c0, uint32_t c0_rs, uint32_t k);

    uint32_t total_;
    uint32_t index_;
    uint32_t remaining_;
    uint32_t cruise_q8_;
    uint32_t c0_q8_;
    uint32_t c0_rs_;        // c0 / sqrt(2)
    uint32_t cross_k_;      // k of the ramp-to-cruise step (trapezoid), else 0xFFFFFFFF
    uint32_t special_q8_;   // that step's interval, or the odd triangle's middle one (0: none)
    bool stopping_;
    uint32_t stop_c0_q8_;   // c0 at a_max while stopping
    uint32_t stop_c0_rs_;
    uint32_t stop_floor_q8_;  // no stop interval shorter than the last step kept
    uint8_t carry_q8_;      // fraction of a tick carried to the next interval
};

}  // namespace fw
