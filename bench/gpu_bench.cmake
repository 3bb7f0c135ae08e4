# gpu_bench (issue 8): ms per frame of every method at 1280x720 and
# 2560x1440, on the GPU by default (bench/gpu_bench.c). Included from
# tests/gpu/CMakeLists.txt. Links the static core for --device-images
# (device buffers through the backend table).
add_executable(gpu_bench ${CMAKE_CURRENT_LIST_DIR}/gpu_bench.c)
target_include_directories(gpu_bench PRIVATE ${PROJECT_SOURCE_DIR}/core)
target_link_libraries(gpu_bench PRIVATE edgewise_core ew_warnings)
if(TARGET edgewise_cuda)
  add_dependencies(gpu_bench edgewise_cuda)
endif()
# the benchmark itself runs only on request; CI checks that it runs (CPU,
# tiny frames) so the GPU figures can be taken whenever a GPU is there
add_test(NAME gpu_bench_smoke COMMAND gpu_bench --device default --frames 1 --sizes 64x48)
set_tests_properties(gpu_bench_smoke PROPERTIES LABELS "gpu;bench")
