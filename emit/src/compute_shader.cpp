// The compute-shader wrapper of compute_shader.hpp.
#include "lgp/emit/compute_shader.hpp"

#include "syntax.hpp"

namespace lgp::emit {

namespace {
// What a language's kernel is made of around the emitted function: its bindings, the row
// count's name, the entry point's opening and the scalar type of `precision`.
struct KernelSyntax {
  std::string bindings, rows, main_open, type;
};

Expected<KernelSyntax> kernelSyntax(Language lang, bool half) {
  if (!languageInfo(lang).shader)
    return Status::error("compute shader: " + std::string(languageInfo(lang).title) +
                         " does not run on a GPU");
  const detail::LanguageSyntax& syn = detail::syntaxOf(lang);
  const Precision p = half ? Precision::Half : Precision::Float;
  return KernelSyntax{std::string(syn.kernel_prologue) +
                          (half ? std::string(syn.kernel_half_line) : std::string()) +
                          std::string(syn.kernel_bindings),
                      std::string(syn.kernel_rows), std::string(syn.kernel_main_open),
                      std::string(syn.scalar_type[static_cast<int>(p)])};
}
}  // namespace

Expected<std::string> computeShader(const Emitted& e, Language lang, Precision precision,
                                    KernelBody body) {
  if (precision == Precision::Double) return Status::error("compute shader: no double precision");
  if (e.output_access.empty() || e.function_name.empty())
    return Status::error("compute shader: the emitted function has no outputs");
  const bool half = precision == Precision::Half;
  auto syn = kernelSyntax(lang, half);
  if (!syn) return syn.status();
  const size_t ni = static_cast<size_t>(e.num_inputs), k = e.output_access.size();
  std::string s = syn->bindings;
  s += "\n" + (body == KernelBody::Formula ? e.code : e.io_baseline) + "\n";
  s += syn->main_open;
  s += "  if (lgp_i >= " + syn->rows + ") return;\n";
  s += "  " + e.return_type + " lgp_v = " + e.function_name + "(";
  for (size_t i = 0; i < ni; ++i) {
    const std::string load =
        "lgp_in[lgp_i * " + std::to_string(ni) + "u + " + std::to_string(i) + "u]";
    s += (i ? ", " : "") + (half ? syn->type + "(" + load + ")" : load);
  }
  s += ");\n";
  for (size_t j = 0; j < k; ++j) {
    const std::string v = "lgp_v" + e.output_access[j];
    s += "  lgp_out[lgp_i * " + std::to_string(k) + "u + " + std::to_string(j) +
         "u] = " + (half ? "float(" + v + ")" : v) + ";\n";
  }
  s += "}\n";
  return s;
}

}  // namespace lgp::emit
