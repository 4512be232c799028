# fb_backend_registry(KIND OUT_LIBS BACKEND...): the registry of a driver folder's enabled
# backends (drivers/camera, drivers/gpio). Each backend folder defines fb_KIND_<name> and its
# header <name>/<name>_KIND.hpp declares `<Kind>Backend <name>_KIND_backend()`. Adds the
# folders, writes KIND_backends.cpp from KIND_backends.cpp.in (@FB_BACKEND_INCLUDES@,
# @FB_BACKEND_ENTRIES@) into the binary folder, and sets OUT_LIBS to the backends' libraries,
# so a disabled backend is not compiled at all.
function(fb_backend_registry kind out_libs)
  file(RELATIVE_PATH folder ${PROJECT_SOURCE_DIR} ${CMAKE_CURRENT_SOURCE_DIR})
  set(FB_BACKEND_INCLUDES "")
  set(FB_BACKEND_ENTRIES "")
  set(libs "")
  foreach(backend IN LISTS ARGN)
    add_subdirectory(${backend})
    string(APPEND FB_BACKEND_INCLUDES "#include \"${folder}/${backend}/${backend}_${kind}.hpp\"\n")
    string(APPEND FB_BACKEND_ENTRIES "      ${backend}_${kind}_backend(),\n")
    list(APPEND libs fb_${kind}_${backend})
  endforeach()
  configure_file(${kind}_backends.cpp.in ${CMAKE_CURRENT_BINARY_DIR}/${kind}_backends.cpp @ONLY)
  set(${out_libs} ${libs} PARENT_SCOPE)
endfunction()
