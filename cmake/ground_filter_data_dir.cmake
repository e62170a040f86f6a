# gf_resolve_data_dir(<repository> <out-var>): the evaluation data folder for the tests at configure
# time, the rule of scripts/common.sh gf_data_dir: $ENV{GF_DATA_DIR} when set (an error when it is
# not a folder), else <repository>/data (scripts/get_data.sh) when it exists, else
# <repository>/../shared/data when it exists. With none, <repository>/data: the data tests then
# report themselves skipped, naming it. Included by CMakeLists.txt (also with
# -DGF_CORE_ONLY=ON); a -DGF_DATA_DIR=... given to CMake comes first (the callers check it).
function(gf_resolve_data_dir repo out)
  get_filename_component(repo "${repo}" REALPATH)
  if(NOT "$ENV{GF_DATA_DIR}" STREQUAL "")
    if(NOT IS_DIRECTORY "$ENV{GF_DATA_DIR}")
      message(FATAL_ERROR "GF_DATA_DIR=$ENV{GF_DATA_DIR} is not a folder: fix or unset it "
                          "(bash scripts/get_data.sh --dest DIR fills a folder)")
    endif()
    get_filename_component(dir "$ENV{GF_DATA_DIR}" REALPATH)
  elseif(IS_DIRECTORY "${repo}/data")
    set(dir "${repo}/data")
  elseif(IS_DIRECTORY "${repo}/../shared/data")
    get_filename_component(dir "${repo}/../shared/data" REALPATH)
  else()
    set(dir "${repo}/data")
  endif()
  set(${out} "${dir}" PARENT_SCOPE)
endfunction()
