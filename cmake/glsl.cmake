# GLSL -> SPIR-V at build time, embedded as C arrays (no shader files at run time).
# voxtier_glsl(<target> <name> <source> [DEFINES d...] [DEPENDS header...]) compiles
# <module>/shaders/<source> into <build>/<module>/shaders/<name>.h holding `uint32_t <name>[]`
# and adds it to <target>. Every shader depends on the kernel it includes (core/sprite_kernel.h)
# and on the headers it shares with its C++ host (DEPENDS), so editing either rebuilds it.
function(voxtier_glsl target name source)
    cmake_parse_arguments(G "" "" "DEFINES;DEPENDS" ${ARGN})
    set(out_dir ${CMAKE_CURRENT_BINARY_DIR}/shaders)
    set(defines)
    foreach(d ${G_DEFINES})
        list(APPEND defines -D${d})
    endforeach()
    add_custom_command(
        OUTPUT ${out_dir}/${name}.h
        COMMAND ${CMAKE_COMMAND} -E make_directory ${out_dir}
        COMMAND ${GLSLANG_VALIDATOR} -V --target-env vulkan1.2 -I${PROJECT_SOURCE_DIR} ${defines}
                --vn ${name} -o ${out_dir}/${name}.h ${CMAKE_CURRENT_SOURCE_DIR}/shaders/${source}
        DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/shaders/${source} ${PROJECT_SOURCE_DIR}/core/sprite_kernel.h
                ${G_DEPENDS}
        COMMENT "glslang: ${source} -> shaders/${name}.h"
        VERBATIM)
    target_sources(${target} PRIVATE ${out_dir}/${name}.h)
    target_include_directories(${target} PRIVATE ${CMAKE_CURRENT_BINARY_DIR})
endfunction()
