# Turns web/index.html into a C++ header holding it as a raw string literal (cmake -P script).
# Inputs: IN (html file), OUT (header to write).
file(READ ${IN} LGPD_HTML)
string(FIND "${LGPD_HTML}" ")lgpd_html\"" LGPD_CLASH)
if(NOT LGPD_CLASH EQUAL -1)
  message(FATAL_ERROR "${IN} contains the raw-string delimiter )lgpd_html\"")
endif()
file(WRITE ${OUT}.tmp
  "// Generated from frontends/lgpd/web/index.html by embed_web.cmake. Do not edit.\n"
  "#pragma once\n"
  "namespace lgpd::web {\n"
  "inline constexpr const char kIndexHtml[] = R\"lgpd_html(${LGPD_HTML})lgpd_html\";\n"
  "}  // namespace lgpd::web\n")
file(COPY_FILE ${OUT}.tmp ${OUT} ONLY_IF_DIFFERENT)
file(REMOVE ${OUT}.tmp)
