# Checks that the C++ sources follow the tree's .clang-format, with the one
# version of clang-format whose output it was written for (14).
#   cmake -DCLANG_FORMAT=<clang-format-14> -DSOURCE_DIR=<tree> -P check_format.cmake
cmake_minimum_required(VERSION 3.16)
if(NOT CLANG_FORMAT OR NOT SOURCE_DIR)
  message(FATAL_ERROR "usage: cmake -DCLANG_FORMAT=<clang-format-14> -DSOURCE_DIR=<tree> -P check_format.cmake")
endif()
set(files "")
foreach(dir include src tests bench fuzz)
  file(GLOB_RECURSE found "${SOURCE_DIR}/${dir}/*.cpp" "${SOURCE_DIR}/${dir}/*.hpp")
  list(APPEND files ${found})
endforeach()
list(LENGTH files count)
execute_process(COMMAND ${CLANG_FORMAT} --style=file --dry-run -Werror ${files}
                RESULT_VARIABLE failed ERROR_VARIABLE errors)
if(failed)
  message(FATAL_ERROR "${errors}\nreformat with: clang-format-14 -i <files> (from the tree's root)")
endif()
message(STATUS "${count} files follow .clang-format")
