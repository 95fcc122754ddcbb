// Skipping GPU tests where no GPU is usable (CI, machines without a driver).
#pragma once

#include <gtest/gtest.h>

#include <string>

#include "device/device.h"

#define CINEVOL_REQUIRE_CUDA()                                                \
  do {                                                                        \
    std::string why_no_gpu;                                                   \
    if (!::cinevol::CudaAvailable(&why_no_gpu)) GTEST_SKIP() << "no usable GPU: " << why_no_gpu; \
  } while (0)
