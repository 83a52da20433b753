// StepPlanner: trapezoidal (or triangular) step timing for one move, in integer math.
// Contract: begin(steps, rate, accel) plans exactly `steps` steps; next_interval()
// returns, step by step, the time from the previous step edge (from the start, for the
// first) in STEP_TICK_HZ ticks, until finished(). rate and accel are clamped to >= 1
// (the Device validates them against cfg first).
//
// Method: every step lands where the closed-form trapezoid (host motion/trapezoid.py)
// crosses that position. Step i (0-based) is timed by k = min(i, steps-1-i), its
// distance from the nearer end, so the profile is symmetric by construction. On the
// ramps the interval is ramp(k) = c0 (sqrt(k+1) - sqrt(k)), c0 = f sqrt(2/a): from a
// table for k < 8, then by D. Austin's recurrence ramp(k) = ramp(k-1) (4k-1)/(4k+1)
// (error < 3e-4 per step there, < 0.1 % summed), run backwards while decelerating: one
// 32-bit division per ramp step, none while cruising. ramp() is kept as a normalised
// 30-bit mantissa and a shift, so long slow ramps keep full precision. The one step that
// crosses from ramp to cruise, and the middle step of an odd triangular move, get their
// exact closed-form interval, computed once per move (a few 64-bit operations and
// square roots, about a millisecond on the AVR). Times carry their fraction of a tick
// (24.8 fixed point) from step to step, so rounding never accumulates.
#pragma once
#include <stdint.h>

namespace fw {

uint32_t isqrt64(uint64_t x);

class StepPlanner {
public:
    StepPlanner();
    void begin(uint32_t steps, uint32_t rate_steps_per_s, uint32_t accel_steps_per_s2);
    void abort() { remaining_ = 0; }
    bool finished() const { return remaining_ == 0; }
    uint32_t remaining() const { return remaining_; }
    // Call only while !finished().
    uint32_t next_interval();

private:
    void set_ramp_table(uint32_t k);
    void move_ramp_to(uint32_t k);
    uint32_t ramp_q8() const { return ramp_m_ >> ramp_e_; }

    uint32_t total_;
    uint32_t index_;
    uint32_t remaining_;
    uint32_t cruise_q8_;
    uint32_t c0_q8_;
    uint32_t cross_k_;      // k of the ramp-to-cruise step (trapezoid), else 0xFFFFFFFF
    uint32_t special_q8_;   // that step's interval, or the odd triangle's middle one
    uint32_t ramp_k_;       // the mantissa below holds ramp(ramp_k_)
    uint32_t ramp_m_;       // ramp(k) in q8 == ramp_m_ >> ramp_e_, ramp_m_ in [2^29, 2^30)
    uint8_t ramp_e_;
    uint8_t carry_q8_;      // fraction of a tick carried to the next interval
};

}  // namespace fw
