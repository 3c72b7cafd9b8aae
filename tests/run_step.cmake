# Helpers of the consumer tests (cmake -P scripts).

# require_variables(script var...): stops, naming the script, unless every
# variable was given with -D.
function(require_variables script)
  foreach(variable IN LISTS ARGN)
    if(NOT DEFINED ${variable})
      message(FATAL_ERROR "${script} needs -D${variable}=...")
    endif()
  endforeach()
endfunction()

# run_step(name command...): runs one step of a consumer test; a failing
# step fails the test and shows that step's output.
function(run_step name)
  list(JOIN ARGN " " command)
  message(STATUS "${name}: ${command}")
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE result OUTPUT_VARIABLE output ERROR_VARIABLE output)
  if(NOT result EQUAL 0)
    message(FATAL_ERROR "${name} failed (${result}):\n${output}")
  endif()
  message(STATUS "${name} output:\n${output}")
endfunction()
