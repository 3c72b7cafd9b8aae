# Installs the built project into a fresh prefix, then configures, builds and
# runs the consumer project against it. Run with cmake -P; any failing step
# fails the test and shows that step's output.
include("${CMAKE_CURRENT_LIST_DIR}/run_step.cmake")
require_variables(install_consumer.cmake PWCONTACT_BINARY_DIR CONSUMER_SOURCE_DIR WORK_DIR CMAKE_CXX_COMPILER)

set(prefix "${WORK_DIR}/prefix")
set(build "${WORK_DIR}/build")
file(REMOVE_RECURSE "${WORK_DIR}")

# The consumer is built with the flags and build type of the project's own
# build: a library instrumented with sanitizers links only into code built
# with the same runtime.
load_cache("${PWCONTACT_BINARY_DIR}" READ_WITH_PREFIX PARENT_
  CMAKE_BUILD_TYPE CMAKE_CXX_FLAGS CMAKE_EXE_LINKER_FLAGS)


run_step(install "${CMAKE_COMMAND}" --install "${PWCONTACT_BINARY_DIR}" --prefix "${prefix}")
run_step(configure "${CMAKE_COMMAND}" -S "${CONSUMER_SOURCE_DIR}" -B "${build}"
  "-DCMAKE_PREFIX_PATH=${prefix}"
  -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF
  "-DCMAKE_CXX_COMPILER=${CMAKE_CXX_COMPILER}"
  "-DCMAKE_BUILD_TYPE=${PARENT_CMAKE_BUILD_TYPE}"
  "-DCMAKE_CXX_FLAGS=${PARENT_CMAKE_CXX_FLAGS}"
  "-DCMAKE_EXE_LINKER_FLAGS=${PARENT_CMAKE_EXE_LINKER_FLAGS}")

# The package must come from the fresh prefix, not from some other install.
load_cache("${build}" READ_WITH_PREFIX CONSUMER_ pwcontact_DIR)
string(FIND "${CONSUMER_pwcontact_DIR}" "${prefix}/" position)
if(NOT position EQUAL 0)
  message(FATAL_ERROR "the consumer found pwcontact in ${CONSUMER_pwcontact_DIR}, not under ${prefix}")
endif()

run_step(build "${CMAKE_COMMAND}" --build "${build}")
run_step(run "${build}/pwcontact_consumer")
