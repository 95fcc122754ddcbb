# Decides whether the CUDA backends are built and sets CINEVOL_HAVE_CUDA.
# The machines that build cinevol have nvcc but often no GPU: CUDA code must
# compile everywhere, and run-time checks pick the backend.
set(CINEVOL_HAVE_CUDA OFF)
if(NOT CINEVOL_CUDA STREQUAL "OFF")
  if(NOT CMAKE_CUDA_COMPILER AND EXISTS /usr/local/cuda/bin/nvcc)
    set(CMAKE_CUDA_COMPILER /usr/local/cuda/bin/nvcc)
  endif()
  include(CheckLanguage)
  check_language(CUDA)
  if(CMAKE_CUDA_COMPILER)
    # sm_90 machine code for H100/H200, plus PTX so newer GPUs can JIT it.
    if(NOT DEFINED CMAKE_CUDA_ARCHITECTURES)
      set(CMAKE_CUDA_ARCHITECTURES 90-real 90-virtual)
    endif()
    enable_language(CUDA)
    set(CMAKE_CUDA_STANDARD 17)  # CMake 3.25 has no C++20 dialect for nvcc
    set(CMAKE_CUDA_STANDARD_REQUIRED ON)
    find_package(CUDAToolkit REQUIRED)
    set(CINEVOL_HAVE_CUDA ON)
  elseif(CINEVOL_CUDA STREQUAL "ON")
    message(FATAL_ERROR "CINEVOL_CUDA=ON but no CUDA compiler was found")
  endif()
endif()
message(STATUS "cinevol: CUDA backends ${CINEVOL_HAVE_CUDA}")
