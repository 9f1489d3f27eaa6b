# OpenCV's modules as imported targets (opencv_core, opencv_imgproc, ...) found by their headers and libraries,
# without OpenCV's CMake config. Debian 12 ships that config only in libopencv-dev, which depends on every module
# (Qt, VTK, GDAL, MPI and FFmpeg's headers: 118 more packages, 87 MB more to download and 444 MB more installed on
# a fresh machine, bench/results/build.md). aosr uses four modules, each its own package (libopencv-core-dev, ...).
#   aosr_find_opencv_modules(REQUIRED core imgproc)   -- a fatal error names the missing package
#   aosr_find_opencv_modules(OPTIONAL superres)       -- sets AOSR_OPENCV_<module>_FOUND
# A module already defined as a target (OpenCV's config loaded by someone else) is kept as it is.
function(aosr_find_opencv_modules mode)
  find_path(AOSR_OPENCV_INCLUDE_DIR opencv2/core.hpp PATH_SUFFIXES opencv4)
  foreach(m IN LISTS ARGN)
    string(REPLACE "_" "-" package "libopencv-${m}-dev")
    if(TARGET opencv_${m})
      set(AOSR_OPENCV_${m}_FOUND TRUE PARENT_SCOPE)
      continue()
    endif()
    find_path(AOSR_OPENCV_${m}_HEADER opencv2/${m}.hpp HINTS ${AOSR_OPENCV_INCLUDE_DIR} PATH_SUFFIXES opencv4)
    find_library(AOSR_OPENCV_${m}_LIBRARY opencv_${m})
    if(AOSR_OPENCV_INCLUDE_DIR AND AOSR_OPENCV_${m}_HEADER AND AOSR_OPENCV_${m}_LIBRARY)
      add_library(opencv_${m} SHARED IMPORTED GLOBAL)
      set_target_properties(opencv_${m} PROPERTIES IMPORTED_LOCATION "${AOSR_OPENCV_${m}_LIBRARY}"
                            INTERFACE_INCLUDE_DIRECTORIES "${AOSR_OPENCV_INCLUDE_DIR}")
      set(AOSR_OPENCV_${m}_FOUND TRUE PARENT_SCOPE)
    elseif(mode STREQUAL "REQUIRED")
      message(FATAL_ERROR "OpenCV's ${m} module (opencv2/${m}.hpp, libopencv_${m}.so) not found: "
                          "install Debian's ${package} (scripts/setup.sh does)")
    else()
      set(AOSR_OPENCV_${m}_FOUND FALSE PARENT_SCOPE)
    endif()
  endforeach()
endfunction()
