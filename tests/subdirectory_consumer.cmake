# Configures, builds and runs the consumer project with pwcontact's source
# tree pulled in by add_subdirectory, with no build type of its own (which
# pwcontact must leave empty), and without the x86 kernels
# (PWCONTACT_SIMD_KERNELS=OFF: the portable build other processors get).
# Run with cmake -P; any failing step fails the test and shows that step's
# output.
include("${CMAKE_CURRENT_LIST_DIR}/run_step.cmake")
require_variables(subdirectory_consumer.cmake PWCONTACT_SOURCE_DIR CONSUMER_SOURCE_DIR WORK_DIR CMAKE_CXX_COMPILER)

set(build "${WORK_DIR}/build")
file(REMOVE_RECURSE "${WORK_DIR}")


run_step(configure "${CMAKE_COMMAND}" -S "${CONSUMER_SOURCE_DIR}" -B "${build}"
  "-DPWCONTACT_SOURCE_DIR=${PWCONTACT_SOURCE_DIR}"
  -DPWCONTACT_SIMD_KERNELS=OFF
  "-DCMAKE_CXX_COMPILER=${CMAKE_CXX_COMPILER}")
load_cache("${build}" READ_WITH_PREFIX CONSUMER_ CMAKE_BUILD_TYPE)
if(NOT "${CONSUMER_CMAKE_BUILD_TYPE}" STREQUAL "")
  message(FATAL_ERROR "the parent's build type became '${CONSUMER_CMAKE_BUILD_TYPE}'")
endif()
include(ProcessorCount)
ProcessorCount(cores)
run_step(build "${CMAKE_COMMAND}" --build "${build}" -j ${cores})
run_step(run "${build}/pwcontact_consumer")
