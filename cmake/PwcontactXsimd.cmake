# xsimd 8.1 as Debian ships it exports a target `xsimd` that links a
# non-existent `xtl`. We only need its headers, so take the include path it
# reports and wrap it in our own interface target. It is used at build time
# only (the public headers have no SIMD types) and never exported.
find_package(xsimd 8.1 REQUIRED CONFIG)
if(NOT xsimd_INCLUDE_DIRS)
  get_target_property(xsimd_INCLUDE_DIRS xsimd INTERFACE_INCLUDE_DIRECTORIES)
endif()
add_library(pwcontact_xsimd INTERFACE)
target_include_directories(pwcontact_xsimd SYSTEM INTERFACE ${xsimd_INCLUDE_DIRS})
