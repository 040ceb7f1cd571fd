# Runs fastddsgen on each IDL file and keeps only the files of the IDL's own types
# (cmake -P, from drivers/dds/CMakeLists.txt).
#   FASTDDSGEN  the generator
#   IDL_ROOT    folder the IDL paths are relative to (also its include path)
#   OUT_ROOT    generated code goes to OUT_ROOT/<idl path's folder>/
#   IDLS        ;-separated IDL paths relative to IDL_ROOT, without ".idl"
# fastddsgen writes the types an IDL includes into its output folder as well; generating each
# IDL in a scratch folder and copying only its own four files keeps two IDLs that include the
# same type from writing the same file, and copy_if_different leaves unchanged files' stamps
# alone so an unchanged IDL recompiles nothing.
foreach(idl IN LISTS IDLS)
    get_filename_component(folder "${idl}" DIRECTORY)
    get_filename_component(type "${idl}" NAME)
    set(scratch "${OUT_ROOT}/.scratch/${idl}")
    file(REMOVE_RECURSE "${scratch}")
    file(MAKE_DIRECTORY "${scratch}" "${OUT_ROOT}/${folder}")
    execute_process(
        COMMAND "${FASTDDSGEN}" -cs -replace -I "${IDL_ROOT}" -d "${scratch}" "${IDL_ROOT}/${idl}.idl"
        RESULT_VARIABLE result OUTPUT_VARIABLE output ERROR_VARIABLE output)
    if(NOT result EQUAL 0 OR NOT EXISTS "${scratch}/${type}PubSubTypes.cxx")
        message(FATAL_ERROR "fastddsgen failed on ${IDL_ROOT}/${idl}.idl:\n${output}")
    endif()
    foreach(suffix .h .cxx PubSubTypes.h PubSubTypes.cxx)
        file(COPY_FILE "${scratch}/${type}${suffix}" "${OUT_ROOT}/${folder}/${type}${suffix}"
             ONLY_IF_DIFFERENT)
    endforeach()
    file(REMOVE_RECURSE "${scratch}")
endforeach()
