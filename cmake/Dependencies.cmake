# Every dependency comes from Debian 12's packages (scripts/setup.sh installs them).
find_package(PkgConfig REQUIRED)
find_package(Eigen3 3.4 REQUIRED NO_MODULE)
find_package(OpenImageIO REQUIRED)  # Only in the lightstage_oiio module, the viewer and tests.
find_package(OpenEXR REQUIRED)
find_package(JPEG REQUIRED)  # libjpeg-turbo (libjpeg-dev): RTI sets and OpenLIME planes.
find_package(PNG REQUIRED)  # libpng (libpng-dev): frames and previews.
find_package(Imath REQUIRED)
find_package(TBB REQUIRED)
find_package(nlohmann_json 3.10 REQUIRED)
find_package(CLI11 REQUIRED)
find_package(Ceres REQUIRED)
find_package(Threads REQUIRED)
find_package(ZLIB REQUIRED)  # CRC-32 of saved frames (zlib1g-dev).
find_package(nanoflann REQUIRED)  # k-d tree over LED directions (libnanoflann-dev).
find_package(tinyobjloader REQUIRED)  # OBJ meshes for render --shape (libtinyobjloader-dev).

# Debian's split OpenCV module packages ship no OpenCVConfig.cmake: define imported targets.
find_path(OPENCV_INCLUDE_DIR opencv2/core.hpp PATH_SUFFIXES opencv4 REQUIRED)
foreach(module core imgproc imgcodecs photo calib3d videoio video)
  find_library(OPENCV_${module}_LIBRARY opencv_${module} REQUIRED)
  add_library(opencv::${module} UNKNOWN IMPORTED)
  # SYSTEM include: OpenCV 4.6 headers warn under C++20.
  set_target_properties(opencv::${module} PROPERTIES
    IMPORTED_LOCATION "${OPENCV_${module}_LIBRARY}"
    INTERFACE_SYSTEM_INCLUDE_DIRECTORIES "${OPENCV_INCLUDE_DIR}"
    INTERFACE_INCLUDE_DIRECTORIES "${OPENCV_INCLUDE_DIR}")
endforeach()
set_property(TARGET opencv::imgproc APPEND PROPERTY INTERFACE_LINK_LIBRARIES opencv::core)
set_property(TARGET opencv::imgcodecs APPEND PROPERTY INTERFACE_LINK_LIBRARIES opencv::imgproc)
set_property(TARGET opencv::photo APPEND PROPERTY INTERFACE_LINK_LIBRARIES opencv::imgproc)
set_property(TARGET opencv::calib3d APPEND PROPERTY INTERFACE_LINK_LIBRARIES opencv::imgproc)
set_property(TARGET opencv::videoio APPEND PROPERTY INTERFACE_LINK_LIBRARIES opencv::imgproc)
set_property(TARGET opencv::video APPEND PROPERTY INTERFACE_LINK_LIBRARIES opencv::imgproc)

# Hardware back-ends (pkg-config only): LEDs through libgpiod 1.6, cameras through Aravis 0.8
# (which needs libusb-1.0-0-dev for pkg-config to resolve it).
pkg_check_modules(GPIOD REQUIRED IMPORTED_TARGET libgpiodcxx)
pkg_check_modules(ARAVIS REQUIRED IMPORTED_TARGET aravis-0.8)
# DSLR domes: tethered cameras through libgphoto2 2.5, their raw files through LibRaw 0.20 (the
# thread-safe libraw_r), test DNGs written through libtiff.
pkg_check_modules(GPHOTO2 REQUIRED IMPORTED_TARGET libgphoto2)
pkg_check_modules(LIBRAW REQUIRED IMPORTED_TARGET libraw_r)
pkg_check_modules(MATIO REQUIRED IMPORTED_TARGET matio)  # Ground-truth .mat files (bench normals).
find_package(TIFF REQUIRED)

# The viewer: GLFW window + OpenGL 3.3 core (no loader: GL_GLEXT_PROTOTYPES against
# libglvnd's libOpenGL), Dear ImGui from Debian's pkg-config file (includes the GLFW/GL3 back-ends).
find_package(glfw3 REQUIRED)
set(OpenGL_GL_PREFERENCE GLVND)
find_package(OpenGL REQUIRED)
pkg_check_modules(IMGUI REQUIRED IMPORTED_TARGET imgui)

if(LIGHTSTAGE_BUILD_TESTS)
  find_package(GTest REQUIRED)
endif()
if(LIGHTSTAGE_BUILD_BENCHMARKS)
  find_package(benchmark REQUIRED)
endif()

# Runs across machines (MPI): optional. Without MPI everything builds and runs as one process.
find_package(MPI COMPONENTS CXX)

# Python bindings (python/): optional, built when pybind11 and NumPy are found (Debian:
# pybind11-dev, python3-numpy). The static libraries are then position-independent, since the
# extension module is a shared object that links them.
option(LIGHTSTAGE_PYTHON "Build the Python bindings when pybind11 and NumPy are found" ON)
set(LIGHTSTAGE_WITH_PYTHON OFF)
if(LIGHTSTAGE_PYTHON AND NOT LIGHTSTAGE_FUZZ)
  # The system's Python (Debian's, with python3-numpy), not whichever a version manager puts first
  # on PATH; -DPython3_EXECUTABLE=... chooses another.
  if(NOT DEFINED Python3_EXECUTABLE AND EXISTS /usr/bin/python3)
    set(Python3_EXECUTABLE /usr/bin/python3 CACHE FILEPATH "Python the bindings are built for")
  endif()
  find_package(Python3 COMPONENTS Interpreter Development.Module NumPy)
  set(PYBIND11_FINDPYTHON ON)
  find_package(pybind11 2.10 CONFIG QUIET)
  if(NOT Python3_FOUND)
    message(STATUS "Python bindings skipped: no Python 3 with its headers (python3-dev)")
  elseif(NOT Python3_NumPy_FOUND)
    message(STATUS "Python bindings skipped: NumPy not found (python3-numpy)")
  elseif(NOT pybind11_FOUND)
    message(STATUS "Python bindings skipped: pybind11 not found (pybind11-dev)")
  else()
    set(LIGHTSTAGE_WITH_PYTHON ON)
    message(STATUS "Python bindings: pybind11 ${pybind11_VERSION}, Python ${Python3_VERSION}")
  endif()
endif()
