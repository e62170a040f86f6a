# Helpers of the CUDA builds: the catkin package (CMakeLists.txt) and -DGF_CUDA=ON
# (cmake/gf_core_only.cmake).
# CMake 3.16 syntax: the top level includes this before it knows whether CUDA can be built.

# gf_nvcc_version(<nvcc> <out_var>): "X.Y" from `nvcc --version`, empty when it cannot be read.
function(gf_nvcc_version nvcc out_var)
  execute_process(COMMAND "${nvcc}" --version OUTPUT_VARIABLE out ERROR_QUIET
                  RESULT_VARIABLE rc)
  set(version "")
  if(rc EQUAL 0 AND out MATCHES "release ([0-9]+\\.[0-9]+)")
    set(version "${CMAKE_MATCH_1}")
  endif()
  set(${out_var} "${version}" PARENT_SCOPE)
endfunction()

# gf_cuda_default_architectures(<nvcc> <out_var>): the default CMAKE_CUDA_ARCHITECTURES.
# CMake >= 3.23: `all-major` (machine code for every major architecture the toolkit supports and
# PTX of the newest; CMake >= 3.23 with nvcc >= 11.5 passes `-arch=all-major` to nvcc itself, so
# the list comes from the toolkit). Jetson Xavier (7.2) runs the sm_70 code, Orin (8.7) the sm_80
# code. Older CMake: the GPUs below that this toolkit supports (`nvcc --list-gpu-arch`, CUDA >= 11):
# Jetson Xavier 72, Turing 75, A100 80, Ampere 86, Jetson Orin 87, Ada 89, Hopper 90, the newest
# also as PTX. Not `native`: it fits only the build machine's GPU (no good for a shipped package).
function(gf_cuda_default_architectures nvcc out_var)
  if(NOT CMAKE_VERSION VERSION_LESS 3.23)
    set(${out_var} all-major PARENT_SCOPE)
    return()
  endif()
  set(wanted 72 75 80 86 87 89 90)
  execute_process(COMMAND "${nvcc}" --list-gpu-arch OUTPUT_VARIABLE out ERROR_QUIET
                  RESULT_VARIABLE rc)
  set(supported "")
  if(rc EQUAL 0)
    string(REGEX MATCHALL "compute_[0-9]+" archs "${out}")
    foreach(a IN LISTS archs)
      string(REPLACE "compute_" "" n "${a}")
      list(APPEND supported "${n}")
    endforeach()
  endif()
  if(NOT supported)  # old nvcc without --list-gpu-arch: trust the wanted list
    set(supported ${wanted})
  endif()
  set(result "")
  set(last "")
  foreach(a IN LISTS wanted)
    list(FIND supported "${a}" i)
    if(i GREATER -1)
      if(last)
        list(APPEND result "${last}-real")
      endif()
      set(last "${a}")
    endif()
  endforeach()
  if(last)
    list(APPEND result "${last}")  # machine code and PTX
  else()
    list(GET supported 0 first)  # none of the wanted ones: the oldest the toolkit has
    set(result "${first}")
  endif()
  set(${out_var} "${result}" PARENT_SCOPE)
endfunction()
