# Turns web/index.html and web/app.js into a C++ header holding them as raw string literals
# (cmake -P script). Inputs: IN (html file), IN_JS (the page's script), OUT (header to write).
cmake_minimum_required(VERSION 3.22)
if(NOT IN OR NOT IN_JS OR NOT OUT)
  message(FATAL_ERROR "embed_web.cmake needs -DIN=... -DIN_JS=... -DOUT=...")
endif()
file(WRITE ${OUT}.tmp
  "// Generated from frontends/lgpd/web/ by embed_web.cmake. Do not edit.\n"
  "#pragma once\n"
  "namespace lgpd::web {\n")
function(embed name file)
  file(READ ${file} text)
  string(FIND "${text}" ")lgpd_web\"" clash)
  if(NOT clash EQUAL -1)
    message(FATAL_ERROR "${file} contains the raw-string delimiter )lgpd_web\"")
  endif()
  file(APPEND ${OUT}.tmp "inline constexpr const char ${name}[] = R\"lgpd_web(${text})lgpd_web\";\n")
endfunction()
embed(kIndexHtml ${IN})
embed(kAppJs ${IN_JS})
file(APPEND ${OUT}.tmp "}  // namespace lgpd::web\n")
file(COPY_FILE ${OUT}.tmp ${OUT} ONLY_IF_DIFFERENT)
file(REMOVE ${OUT}.tmp)
