# cmake -DINPUT=<file> -DOUTPUT=<header> -DNAME=<identifier> -P embed_text.cmake
# Writes <header> holding the file's bytes as `inline constexpr char NAME[]`, NUL-terminated: text
# a binary needs at run time (a template, a script), embedded like the SPIR-V so the binary runs
# from any directory, from a clean clone's build and from an install.
file(READ "${INPUT}" hex HEX)
string(REGEX REPLACE "([0-9a-f][0-9a-f])" "'\\\\x\\1'," bytes "${hex}")
string(REPLACE "'\\x0a'," "'\\x0a',\n    " bytes "${bytes}") # one line of the file per line
file(WRITE "${OUTPUT}.tmp"
    "// Generated from ${INPUT} by cmake/embed_text.cmake: edit that file, not this one.\n"
    "#pragma once\n"
    "inline constexpr char ${NAME}[] = {\n    ${bytes}'\\0'};\n")
file(COPY_FILE "${OUTPUT}.tmp" "${OUTPUT}" ONLY_IF_DIFFERENT)
file(REMOVE "${OUTPUT}.tmp")
