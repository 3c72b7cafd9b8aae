# `mpirun -np N pwcontact-mpi screen ARGS` writes what `pwcontact screen ARGS`
# writes, byte for byte: for 3,000 random spheroids (axes text, in a periodic
# box and in open boundaries), the triclinic and 2D GSD test scenes, each
# output kind, with and without mu^2; and a missing input fails with the
# command's message, once.
# cmake -DPWCONTACT_CLI=... -DPWCONTACT_MPI_CLI=... -DMPIEXEC=... -DPYTHON=...
#       -DRANKS=N -DDATA=tests/data -DWORK=dir -P cli_mpi_test.cmake
include(${CMAKE_CURRENT_LIST_DIR}/run_step.cmake)
require_variables(cli_mpi_test.cmake PWCONTACT_CLI PWCONTACT_MPI_CLI MPIEXEC PYTHON RANKS DATA
                  WORK)
file(REMOVE_RECURSE "${WORK}")
file(MAKE_DIRECTORY "${WORK}")
set(mpirun ${MPIEXEC} -n ${RANKS} --allow-run-as-root --oversubscribe)
# Spheroids of equatorial radius 0.2 .. 0.5 and aspect ratio 1/3 .. 3 at
# random in a periodic box of 10 (packing fraction ~0.2, with overlaps).
file(WRITE ${WORK}/scene.py [=[
import math, random
random.seed(5)
with open("scene.axes", "w") as out:
    for _ in range(3000):
        a = random.uniform(0.2, 0.5)
        c = a * math.exp(random.uniform(math.log(1 / 3), math.log(3)))
        q = [random.gauss(0, 1) for _ in range(4)]
        n = math.sqrt(sum(x * x for x in q))
        x = [random.uniform(0, 10) for _ in range(3)]
        out.write(" ".join(f"{v:.17g}" for v in x + [a, a, c] + [v / n for v in q]) + "\n")
]=])
execute_process(COMMAND ${PYTHON} scene.py WORKING_DIRECTORY ${WORK} RESULT_VARIABLE made)
if(NOT made EQUAL 0)
  message(FATAL_ERROR "the scene could not be made (${made})")
endif()
set(cases
  "scene.axes|--format|axes|--box|10|10|10|--cutoff|1.2|--with-mu2"
  "scene.axes|--format|axes|--box|10|10|10|--cutoff|1.1|--outputs|counts"
  "scene.axes|--format|axes|--box|10|10|10|0.3|0.1|0.2|--outputs|neighbors|--with-mu2"
  "scene.axes|--format|axes|--cutoff|1.3|--outputs|neighbors"
  "${DATA}/hoomd_triclinic.gsd|--cutoff|1.5|--with-mu2"
  "${DATA}/hoomd_ellipses_2d.gsd|--cutoff|1.5|--outputs|neighbors")
set(index 0)
foreach(case IN LISTS cases)
  string(REPLACE "|" ";" arguments "${case}")
  list(GET arguments 0 input)
  list(REMOVE_AT arguments 0)
  if(NOT IS_ABSOLUTE "${input}")
    set(input "${WORK}/${input}")
  endif()
  math(EXPR index "${index} + 1")
  run_step(one_process_${index} ${PWCONTACT_CLI} screen ${input} ${arguments} --threads 1
           -o ${WORK}/one_${index}.txt)
  run_step(over_ranks_${index} ${mpirun} ${PWCONTACT_MPI_CLI} screen ${input} ${arguments}
           --threads 1 -o ${WORK}/ranks_${index}.txt)
  execute_process(COMMAND ${CMAKE_COMMAND} -E compare_files ${WORK}/one_${index}.txt
                          ${WORK}/ranks_${index}.txt RESULT_VARIABLE differ)
  file(SIZE ${WORK}/one_${index}.txt bytes)
  if(differ OR bytes EQUAL 0)
    message(FATAL_ERROR "case ${index} (${case}) on ${RANKS} ranks: outputs differ or are empty "
                        "(${bytes} bytes from one process)")
  endif()
  message(STATUS "case ${index} (${case}): ${bytes} bytes, the same on ${RANKS} ranks")
endforeach()
# A missing input: exit status 1 (an input that cannot be read), the message once.
execute_process(COMMAND ${mpirun} ${PWCONTACT_MPI_CLI} screen ${WORK}/missing.gsd
                RESULT_VARIABLE status ERROR_VARIABLE error OUTPUT_VARIABLE output)
string(REGEX MATCHALL "missing.gsd" named "${error}")
list(LENGTH named times)
if(status EQUAL 0 OR NOT times EQUAL 1)
  message(FATAL_ERROR "a missing input on ${RANKS} ranks: status ${status}, named ${times} times:\n"
                      "${error}")
endif()
message(STATUS "a missing input: status ${status}, named once")
# Its help fits a terminal of 80 columns, as `pwcontact`'s does (cli_test).
execute_process(COMMAND ${mpirun} ${PWCONTACT_MPI_CLI} --help
                RESULT_VARIABLE status OUTPUT_VARIABLE help)
string(REPEAT "[^\n]" 80 eighty_columns)
string(REGEX MATCH "${eighty_columns}[^\n]*" long "${help}")
if(NOT status EQUAL 0 OR help STREQUAL "" OR long)
  message(FATAL_ERROR "pwcontact-mpi --help: status ${status}, a line over 79 columns: '${long}'")
endif()
message(STATUS "pwcontact-mpi --help: every line within 79 columns")
