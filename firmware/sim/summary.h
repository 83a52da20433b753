// The harness's JSON summary: what ran, for how long, and every figure and violation.
#pragma once
#include "harness.h"

int summary_write(const struct harness *h, const char *path, const char *elf, const char *reason, int crashed,
                  double wall_s);
