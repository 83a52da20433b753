// The harness's line to the host's Python plant (tsa_bench.simavr.plant_server).
//
// Contract. A Unix stream socket; all integers little-endian. After connecting, the
// harness sends the 8-byte hello "TSAPLNT1" and waits for one byte 'G' (the host has
// opened the serial port: release the reset). Then each query is a 24-byte request
//   u8 kind ('L' position ADC, 'R' resistance ADC), u8 motor_moving, u8 0, u8 0,
//   i32 steps (A4988 position), f64 t_s (device time), f64 heater_duty (0..1)
// answered by 8 bytes: i32 counts (ADS1115 or CS5513 counts), u8 flags (bit 0 =
// overrange), 3 bytes 0. Queries come in non-decreasing t_s. Any I/O error is fatal
// to the harness (the plant is the truth; no made-up values).
#pragma once
#include <stddef.h>
#include <stdint.h>

struct plant_link;

struct plant_link *plant_connect(const char *path, char *err, size_t errlen);
int plant_wait_start(struct plant_link *p);  // 0 when 'G' arrived, -1 on EOF/error
int plant_query(struct plant_link *p, char kind, double t_s, int32_t steps, int moving, double heater_duty,
                int32_t *counts, uint8_t *flags);
void plant_close(struct plant_link *p);
