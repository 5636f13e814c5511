# Included at each interface package's project() by tools/build_interfaces.sh
# (-DCMAKE_PROJECT_INCLUDE=this file); the packages' own CMakeLists.txt stay as upstream wrote them.
#
# Why: the ros-jazzy PyPI wheels ship CMake export files written on the machine the wheels were
# built on. Their <pkg>__rosidl_generator_py targets name that machine's Python and numpy include
# dirs (/opt/python/cp311-cp311/include/python3.11, .../numpy/_core/include), which exist nowhere
# else, and CMake refuses, at generate time, an imported target whose include dir does not exist.
# The right dirs reach the build anyway: rosidl_generator_py adds this venv's Python3 and NumPy
# include dirs to its own targets. So, once the top-level CMakeLists.txt has run (every
# find_package() has made its imported targets by then), drop the include dirs that do not exist.

function(mta_drop_missing_include_dirs)
  get_directory_property(_targets DIRECTORY "${CMAKE_SOURCE_DIR}" IMPORTED_TARGETS)
  foreach(_target IN LISTS _targets)
    get_target_property(_dirs "${_target}" INTERFACE_INCLUDE_DIRECTORIES)
    if(NOT _dirs)
      continue()
    endif()
    set(_kept "")
    foreach(_dir IN LISTS _dirs)
      # generator expressions are evaluated later: keep them as they are
      if(_dir MATCHES "^\\$<" OR EXISTS "${_dir}")
        list(APPEND _kept "${_dir}")
      else()
        message(STATUS "${_target}: dropping include dir ${_dir} (does not exist)")
      endif()
    endforeach()
    set_target_properties("${_target}" PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${_kept}")
  endforeach()
endfunction()

cmake_language(DEFER DIRECTORY "${CMAKE_SOURCE_DIR}" CALL mta_drop_missing_include_dirs)
