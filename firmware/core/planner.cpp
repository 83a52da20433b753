#include "planner.h"

#include "board.h"

namespace fw {

namespace {

// (sqrt(k+1) - sqrt(k)) * 65536, k = 0..7.
const uint32_t RAMP_TABLE_Q16[8] = {65536, 27146, 20830, 17560, 15471, 13987, 12862, 11972};
const uint32_t TABLE_SIZE = 8;
const uint32_t NONE = 0xFFFFFFFFUL;
const uint32_t M_LOW = 1UL << 29;
const uint32_t M_HIGH = 1UL << 30;
const uint32_t F_Q8 = STEP_TICK_HZ << 8;  // 2e6 * 256 < 2^32

// (a * b) >> 16 for b <= 65536, without 64-bit multiplies.
uint32_t mul_q16(uint32_t a, uint32_t b) {
    return (a >> 16) * b + (((a & 0xFFFFUL) * b) >> 16);
}

// sqrt(n) in 16.16 fixed point.
uint64_t sqrt_q16(uint32_t n) {
    return isqrt64(static_cast<uint64_t>(n) << 32);
}

}  // namespace

uint32_t isqrt64(uint64_t x) {
    uint64_t result = 0;
    uint64_t bit = static_cast<uint64_t>(1) << 62;
    while (bit > x) bit >>= 2;
    while (bit != 0) {
        if (x >= result + bit) {
            x -= result + bit;
            result = (result >> 1) + bit;
        } else {
            result >>= 1;
        }
        bit >>= 2;
    }
    return static_cast<uint32_t>(result);
}

StepPlanner::StepPlanner()
    : total_(0), index_(0), remaining_(0), cruise_q8_(256), c0_q8_(256), cross_k_(NONE), special_q8_(256),
      ramp_k_(0), ramp_m_(M_LOW), ramp_e_(0), carry_q8_(0) {}

void StepPlanner::begin(uint32_t steps, uint32_t rate, uint32_t accel) {
    if (rate == 0) rate = 1;
    if (accel == 0) accel = 1;
    total_ = remaining_ = steps;
    index_ = 0;
    carry_q8_ = 0;
    cruise_q8_ = F_Q8 / rate;
    if (cruise_q8_ < 256) cruise_q8_ = 256;
    // c0 * 256 = sqrt(2 f^2 2^16 / a); 2 * (2e6)^2 * 2^16 < 2^63.
    const uint64_t f = STEP_TICK_HZ;
    c0_q8_ = isqrt64((2 * f * f << 16) / accel);
    if (c0_q8_ < 256) c0_q8_ = 256;
    set_ramp_table(0);
    cross_k_ = NONE;
    special_q8_ = 0;
    const uint64_t v = rate;
    if (static_cast<uint64_t>(steps) * accel > v * v) {
        // Trapezoid: the ramp reaches the rate at s_a = v^2 / 2a; the step ending at
        // position n = floor(s_a) + 1 leaves the ramp, at t = n/v + v/(2a).
        uint32_t x = static_cast<uint32_t>(v * v / (2 * static_cast<uint64_t>(accel)));
        uint64_t t_end = static_cast<uint64_t>(F_Q8) * (x + 1) / rate +
                         static_cast<uint64_t>(F_Q8) * rate / (2 * static_cast<uint64_t>(accel));
        uint64_t t_start = (static_cast<uint64_t>(c0_q8_) * sqrt_q16(x)) >> 16;
        cross_k_ = x;
        special_q8_ = t_end > t_start ? static_cast<uint32_t>(t_end - t_start) : cruise_q8_;
        // When that step is also the middle one it holds both ramp ends: 2 T - 1/v.
        if (steps == 2 * x + 1) special_q8_ = 2 * special_q8_ - cruise_q8_;
    } else if (steps & 1) {
        // Odd triangle: the middle step straddles the peak at t = sqrt(steps / a);
        // it lasts c0 (sqrt(2 steps) - 2 sqrt(m)), m = (steps - 1) / 2.
        uint64_t two_sqrt_m = 2 * sqrt_q16((steps - 1) / 2);
        uint64_t s = sqrt_q16(2 * steps) - two_sqrt_m;
        special_q8_ = static_cast<uint32_t>((static_cast<uint64_t>(c0_q8_) * s) >> 16);
    }
}

void StepPlanner::set_ramp_table(uint32_t k) {
    ramp_k_ = k;
    ramp_m_ = mul_q16(c0_q8_, RAMP_TABLE_Q16[k]);
    ramp_e_ = 0;
    while (ramp_m_ < M_LOW) {
        ramp_m_ <<= 1;
        ++ramp_e_;
    }
}

void StepPlanner::move_ramp_to(uint32_t k) {
    while (ramp_k_ < k) {
        if (ramp_k_ + 1 < TABLE_SIZE) {
            set_ramp_table(ramp_k_ + 1);
            continue;
        }
        ++ramp_k_;
        ramp_m_ -= 2 * ramp_m_ / (4 * ramp_k_ + 1);
        if (ramp_m_ < M_LOW) {
            ramp_m_ <<= 1;
            ++ramp_e_;
        }
    }
    while (ramp_k_ > k) {
        if (ramp_k_ - 1 < TABLE_SIZE) {
            set_ramp_table(ramp_k_ - 1);
            continue;
        }
        ramp_m_ += 2 * ramp_m_ / (4 * ramp_k_ - 1);
        --ramp_k_;
        if (ramp_m_ >= M_HIGH) {
            ramp_m_ >>= 1;
            --ramp_e_;
        }
    }
}

uint32_t StepPlanner::next_interval() {
    if (remaining_ == 0) return 0;
    uint32_t k = index_;
    uint32_t mirror = total_ - 1 - index_;
    if (mirror < k) k = mirror;
    uint32_t q8;
    if (cross_k_ != NONE) {
        if (k > cross_k_) {
            q8 = cruise_q8_;
        } else if (k == cross_k_) {
            q8 = special_q8_;
        } else {
            move_ramp_to(k);
            q8 = ramp_q8();
        }
    } else if (special_q8_ != 0 && index_ == total_ / 2) {
        q8 = special_q8_;
    } else {
        move_ramp_to(k);
        q8 = ramp_q8();
    }
    if (q8 < cruise_q8_) q8 = cruise_q8_;
    uint32_t sum = q8 + carry_q8_;
    carry_q8_ = static_cast<uint8_t>(sum & 0xFF);
    ++index_;
    --remaining_;
    return sum >> 8;
}

}  // namespace fw
