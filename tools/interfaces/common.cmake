# Shared by the interface packages under tools/interfaces, which
# tools/build_interfaces.sh builds with plain cmake against the ros-jazzy-*
# wheels installed in a venv (no colcon, no ROS install).

if(NOT CMAKE_CXX_STANDARD)
  set(CMAKE_CXX_STANDARD 17)
  set(CMAKE_CXX_STANDARD_REQUIRED ON)
endif()

find_package(ament_cmake REQUIRED)
find_package(rosidl_default_generators REQUIRED)

# The wheels' exported <pkg>::<pkg>__rosidl_generator_py targets name the
# Python and numpy include directories of the machine the wheels were built on
# (/opt/python/cp311-cp311/...), which do not exist here, and CMake refuses to
# compile against an imported target with a missing include directory. Point
# every such target at this interpreter's headers instead. Call after the
# dependencies' find_package.
macro(r2d2_fix_imported_python_includes)
  find_package(Python3 REQUIRED COMPONENTS Interpreter Development.Module NumPy)
  get_directory_property(_imported_targets IMPORTED_TARGETS)
  foreach(_target IN LISTS _imported_targets)
    if(_target MATCHES "__rosidl_generator_py$")
      set_target_properties(${_target} PROPERTIES
        INTERFACE_INCLUDE_DIRECTORIES "${Python3_INCLUDE_DIRS};${Python3_NumPy_INCLUDE_DIRS}")
    endif()
  endforeach()
endmacro()

# rclpy loads only the C type support (lib<pkg>__rosidl_typesupport_c, which
# dispatches to the Fast DDS and introspection C libraries) and the Python
# extension. The C++ generators (headers, C++ type supports) serve C++ nodes
# only; with R2D2_INTERFACES_CPP=OFF they are not run, which roughly halves
# the compile time.
option(R2D2_INTERFACES_CPP "also generate the C++ headers and type supports" OFF)
if(NOT R2D2_INTERFACES_CPP)
  list(FILTER AMENT_EXTENSIONS_rosidl_generate_idl_interfaces EXCLUDE REGEX
    "^rosidl_(generator_cpp|typesupport_cpp|typesupport_fastrtps_cpp|typesupport_introspection_cpp):")
endif()
