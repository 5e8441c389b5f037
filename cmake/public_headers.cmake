# Writes a module's installed headers (cmake -P, one run per module): each header of SOURCE_DIR
# named in HEADERS (paths relative to it, comma-separated, as MODULES) to OUTPUT_DIR/voxtier/<same path>, with
# every include of a voxtier module, `#include "core/scene.hpp"`, rewritten as
# `#include <voxtier/core/scene.hpp>`. The source tree includes modules by their folder (the
# repository root is on the include path); an installed tree puts only <prefix>/include there,
# so a consumer writes <voxtier/...> and no folder named core/ or compose/ lands in its
# include namespace.
foreach(var SOURCE_DIR OUTPUT_DIR HEADERS MODULES)
    if(NOT DEFINED ${var})
        message(FATAL_ERROR "public_headers.cmake: -D${var}= is required")
    endif()
endforeach()
string(REPLACE "," "|" modules_alternation "${MODULES}")
string(REPLACE "," ";" HEADERS "${HEADERS}")
foreach(header IN LISTS HEADERS)
    file(READ "${SOURCE_DIR}/${header}" text)
    string(REGEX REPLACE "#include \"((${modules_alternation})/[^\"]*)\"" "#include <voxtier/\\1>"
           text "${text}")
    set(out "${OUTPUT_DIR}/voxtier/${header}")
    # Written only when it changes, so that a rebuild recompiles nothing that includes it.
    set(old "")
    if(EXISTS "${out}")
        file(READ "${out}" old)
    endif()
    if(NOT old STREQUAL text)
        file(WRITE "${out}" "${text}")
    endif()
endforeach()
