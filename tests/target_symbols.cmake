# Checks the kernel objects (one per target, kernels/target.hpp) for
# definitions they share: an inline function or variable defined in two
# objects compiled with different instruction-set flags is one symbol to
# the linker, which keeps either copy, so that the SSE2 path could run code
# compiled for AVX-512. Each object must define its kernel table and no weak
# or unique symbol that another object also defines (compiler-generated
# references to the C++ personality routine aside: data, alike in all).
#   cmake -DNM=<nm> -DOBJECTS=<obj;obj;...> -P target_symbols.cmake
cmake_minimum_required(VERSION 3.16)
if(NOT NM OR NOT OBJECTS)
  message(FATAL_ERROR "usage: cmake -DNM=<nm> -DOBJECTS=<objects> -P target_symbols.cmake")
endif()
list(LENGTH OBJECTS count)
if(count LESS 2)
  message(FATAL_ERROR "expected one object per target, got: ${OBJECTS}")
endif()

set(shared_allowed "DW.ref.__gxx_personality_v0")
set(all "")
foreach(object IN LISTS OBJECTS)
  execute_process(COMMAND ${NM} --defined-only ${object}
                  OUTPUT_VARIABLE listing RESULT_VARIABLE failed ERROR_VARIABLE errors)
  if(failed)
    message(FATAL_ERROR "${NM} failed on ${object}: ${errors}")
  endif()
  get_filename_component(name ${object} NAME)
  if(NOT listing MATCHES "_ZN9pwcontact7kernels[0-9]+kernel_table_")
    message(FATAL_ERROR "${name} defines no pwcontact::kernels::kernel_table_*: is it a kernel object?")
  endif()
  string(REPLACE "\n" ";" lines "${listing}")
  set(mine "")
  foreach(line IN LISTS lines)
    # "<address> <type> <symbol>": W/V weak, u unique, i indirect functions.
    if(line MATCHES "^[0-9a-fA-F]+ ([WVui]) (.+)$")
      list(APPEND mine "${CMAKE_MATCH_2}")
    endif()
  endforeach()
  list(REMOVE_DUPLICATES mine)
  list(APPEND all ${mine})
endforeach()

set(seen "")
set(shared "")
foreach(symbol IN LISTS all)
  if(symbol IN_LIST seen AND NOT symbol IN_LIST shared_allowed AND NOT symbol IN_LIST shared)
    list(APPEND shared "${symbol}")
  endif()
  list(APPEND seen "${symbol}")
endforeach()
if(shared)
  list(JOIN shared "\n  " text)
  message(FATAL_ERROR "kernel objects compiled for different targets define the same weak symbols "
                      "(the linker keeps one copy for all):\n  ${text}\n"
                      "(c++filt demangles them; put them in the target namespace, or make sure they are inlined)")
endif()
list(LENGTH all total)
message(STATUS "${count} kernel objects, ${total} weak symbols, none defined in two")
