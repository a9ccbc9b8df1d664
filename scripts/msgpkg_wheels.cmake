# Included after project() when scripts/build_msgpkg.sh builds a message
# package against the ROS 2 wheels (CMAKE_PROJECT_INCLUDE).
#
# The wheels' exported CMake targets name paths of the machine that built
# them (/opt/python/cp311-cp311/include/python3.11 and numpy's headers there,
# /usr/lib64/libtinyxml2.so), and CMake refuses an imported target whose
# include directory does not exist. Once the CMakeLists has found every
# package, drop from the imported targets the absolute paths that do not
# exist here: this project's own Python headers come from find_package(Python3).
function(_ybg_drop_missing_paths)
  get_directory_property(targets DIRECTORY "${CMAKE_SOURCE_DIR}" IMPORTED_TARGETS)
  foreach(target IN LISTS targets)
    foreach(property INTERFACE_INCLUDE_DIRECTORIES INTERFACE_SYSTEM_INCLUDE_DIRECTORIES
                     INTERFACE_LINK_LIBRARIES)
      get_target_property(values ${target} ${property})
      if(NOT values)
        continue()
      endif()
      set(kept "")
      foreach(value IN LISTS values)
        if(value MATCHES "^/" AND NOT EXISTS "${value}")
          continue()
        endif()
        list(APPEND kept "${value}")
      endforeach()
      set_target_properties(${target} PROPERTIES ${property} "${kept}")
    endforeach()
  endforeach()
endfunction()

cmake_language(DEFER DIRECTORY "${CMAKE_SOURCE_DIR}" CALL _ybg_drop_missing_paths)
