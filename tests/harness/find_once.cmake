# Included by the tests' CMake configures (CMAKE_PROJECT_TOP_LEVEL_INCLUDES,
# harness/build.py find_once_option()): a dependency provider (CMake 3.24+)
# that finds each of YARP's component packages, ACE and YCM once a configure.
#
# The YARP 3.5 of PyPI is a static build whose plugins are linked in: the
# package config of each component finds every component it depends on, and
# theirs, again (ACE ~500 times, YARP_os ~400), which takes 3 s of CPU a
# configure. Found once, the same imported targets exist and the same flags
# and link lines come out (the targets are global; these packages set no
# variable the generated CMakeLists reads but <Package>_FOUND); the configure
# takes 1 s. A user's configure is left as it is: tests/test_install.py and
# tests/test_readme.py configure as a user does, without this file.
macro(ybgc_tests_find_once method name)
  get_property(_ybgc_tests_found GLOBAL PROPERTY "YBGC_TESTS_FOUND_${name}")
  if(_ybgc_tests_found AND "${name}" MATCHES "^(YARP_.+|ACE|YCM)$")
    set(${name}_FOUND TRUE)
  else()
    find_package(${name} ${ARGN} BYPASS_PROVIDER)
    if(${name}_FOUND)
      set_property(GLOBAL PROPERTY "YBGC_TESTS_FOUND_${name}" TRUE)
    endif()
  endif()
endmacro()
cmake_language(SET_DEPENDENCY_PROVIDER ybgc_tests_find_once SUPPORTED_METHODS FIND_PACKAGE)
