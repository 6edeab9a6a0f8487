# kiln_add_blob: compile meshes into a .kiln blob as part of a CMake build.
#
#   kiln_add_blob(TARGET <name> OUTPUT <file.kiln> SOURCES <mesh>...
#                 [ACCEL <kind>...] [OPTIONS <kiln build option>...])
#
# Adds a custom command that runs `kiln build SOURCES -o OUTPUT --accel ... OPTIONS` and a target
# <name> (in ALL) that depends on OUTPUT. Relative SOURCES are relative to the current source
# directory, a relative OUTPUT to the current binary directory (as for add_custom_command).
#
# The blob is rebuilt when
#   - a source changes, or any file its import read (an OBJ's .mtl, a glTF's .bin): kiln writes
#     them to OUTPUT.d (--depfile), which the generator reads back (DEPFILE);
#   - the kiln executable changes (a new compiler version may write different bytes);
#   - SOURCES, ACCEL or OPTIONS change: the arguments go to a stamp file, rewritten only when
#     they change. Make itself never compares command lines; Ninja does, and CMake's Makefile
#     generators delete outputs whose rule changed when they regenerate (CMakeRuleHashes.txt),
#     so the stamp is the generator-independent statement of that dependency.
#
# Needs the executable target Kiln::kiln (find_package(Kiln), or Kiln's own build tree) and a
# generator with DEPFILE support: Ninja, Ninja Multi-Config or Makefiles.

include_guard(GLOBAL)

# Policies are recorded when a function is defined: with CMP0116 NEW, Ninja gets a depfile whose
# paths CMake has resolved itself, as the Makefile generators always do, whatever policy version
# the calling project asks for.
cmake_policy(PUSH)
cmake_policy(SET CMP0116 NEW)

function(kiln_add_blob)
  cmake_parse_arguments(PARSE_ARGV 0 arg "" "TARGET;OUTPUT" "SOURCES;ACCEL;OPTIONS")
  if(arg_UNPARSED_ARGUMENTS)
    message(FATAL_ERROR "kiln_add_blob: unknown arguments: ${arg_UNPARSED_ARGUMENTS}")
  endif()
  foreach(required IN ITEMS TARGET OUTPUT SOURCES)
    if(NOT arg_${required})
      message(FATAL_ERROR "kiln_add_blob: ${required} is required")
    endif()
  endforeach()
  if(NOT TARGET Kiln::kiln)
    message(FATAL_ERROR "kiln_add_blob: no Kiln::kiln target (call find_package(Kiln) first)")
  endif()

  # Absolute paths everywhere: the custom command runs in the current binary directory, and the
  # depfile's target is the -o path as given, which must name the same file as OUTPUT.
  cmake_path(ABSOLUTE_PATH arg_OUTPUT BASE_DIRECTORY "${CMAKE_CURRENT_BINARY_DIR}"
             NORMALIZE OUTPUT_VARIABLE output)
  set(sources "")
  foreach(source IN LISTS arg_SOURCES)
    cmake_path(ABSOLUTE_PATH source BASE_DIRECTORY "${CMAKE_CURRENT_SOURCE_DIR}" NORMALIZE)
    list(APPEND sources "${source}")
  endforeach()
  set(accel_args "")
  foreach(accel IN LISTS arg_ACCEL)
    list(APPEND accel_args --accel "${accel}")
  endforeach()
  set(depfile "${output}.d")

  # The stamp: one argument per line. file(GENERATE) leaves the file (and its time stamp) alone
  # when the content is unchanged, so only a real change of the arguments rebuilds the blob.
  set(stamp "${CMAKE_CURRENT_BINARY_DIR}/CMakeFiles/kiln_add_blob/${arg_TARGET}.args")
  list(JOIN sources "\n" sources_text)
  list(JOIN accel_args "\n" accel_text)
  list(JOIN arg_OPTIONS "\n" options_text)
  file(GENERATE OUTPUT "${stamp}"
       CONTENT "${output}\n${sources_text}\n${accel_text}\n${options_text}\n")

  cmake_path(GET output FILENAME output_name)
  get_filename_component(output_dir "${output}" DIRECTORY)
  add_custom_command(
    OUTPUT "${output}"
    COMMAND "${CMAKE_COMMAND}" -E make_directory "${output_dir}"
    COMMAND "$<TARGET_FILE:Kiln::kiln>" build ${sources} -o "${output}" ${accel_args}
            ${arg_OPTIONS} --depfile "${depfile}"
    # An executable target in DEPENDS is both an ordering dependency (kiln is built first in
    # Kiln's own tree) and a file dependency on the executable: a new kiln rebuilds the blob.
    DEPENDS ${sources} Kiln::kiln "${stamp}"
    DEPFILE "${depfile}"
    COMMENT "Compiling Kiln blob ${output_name}"
    VERBATIM COMMAND_EXPAND_LISTS)
  add_custom_target(${arg_TARGET} ALL DEPENDS "${output}")
endfunction()

cmake_policy(POP)
