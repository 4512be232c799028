#include "host/cli/command_line.hpp"

#include <charconv>
#include <sstream>

namespace fb::cli {

std::string ParsedOptions::get(const std::string& name) const {
  if (auto it = values_.find(name); it != values_.end()) return it->second;
  if (auto it = defaults_.find(name); it != defaults_.end()) return it->second;
  return {};
}

Result<long long> ParsedOptions::get_int(const std::string& name) const {
  const std::string text = get(name);
  long long value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end != text.data() + text.size()) {
    return fail("--" + name + " expects a whole number, got '" + text + "'");
  }
  return value;
}

Result<double> ParsedOptions::get_double(const std::string& name) const {
  const std::string text = get(name);
  try {
    std::size_t used = 0;
    const double value = std::stod(text, &used);
    if (used == text.size()) return value;
  } catch (const std::exception&) {
  }
  return fail("--" + name + " expects a number, got '" + text + "'");
}

Result<ParsedOptions> parse_options(const CommandSpec& spec, const std::vector<std::string>& args,
                                    std::string_view program) {
  const std::string command = std::string(program) + " " + spec.path;
  ParsedOptions parsed;
  for (const auto& option : spec.options) {
    if (!option.default_value.empty()) parsed.defaults_[option.name] = option.default_value;
  }
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& arg = args[i];
    if (arg == "-h" || arg == "--help") {
      parsed.help_requested = true;
      continue;
    }
    if (arg.rfind("--", 0) != 0) {
      return fail("unexpected argument '" + arg + "' for '" + command + "'; see '" + command +
                  " --help'");
    }
    std::string name = arg.substr(2);
    std::optional<std::string> inline_value;
    if (const auto eq = name.find('='); eq != std::string::npos) {
      inline_value = name.substr(eq + 1);
      name = name.substr(0, eq);
    }
    const OptionSpec* option = nullptr;
    for (const auto& candidate : spec.options) {
      if (candidate.name == name) option = &candidate;
    }
    if (option == nullptr) {
      return fail("unknown option '--" + name + "' for '" + command + "'; see '" + command +
                  " --help'");
    }
    if (option->value_name.empty()) {
      if (inline_value) return fail("--" + name + " is a flag and takes no value");
      parsed.values_[name] = "1";
    } else if (inline_value) {
      parsed.values_[name] = *inline_value;
      parsed.all_[name].push_back(*inline_value);
    } else {
      if (i + 1 >= args.size())
        return fail("--" + name + " needs a value (" + option->value_name + ")");
      parsed.values_[name] = args[++i];
      parsed.all_[name].push_back(args[i]);
    }
  }
  return parsed;
}

std::string format_help(const CommandSpec& spec, std::string_view program) {
  std::ostringstream out;
  out << "usage: " << program << " " << spec.path << " [options]\n\n" << spec.summary << "\n";
  if (!spec.options.empty()) out << "\noptions:\n";
  for (const auto& option : spec.options) {
    std::string left = "  --" + option.name;
    if (!option.value_name.empty()) left += " " + option.value_name;
    out << left;
    out << std::string(left.size() < 28 ? 28 - left.size() : 1, ' ') << option.help;
    if (!option.default_value.empty()) out << " (default: " << option.default_value << ")";
    out << "\n";
  }
  out << "  -h, --help                show this help\n";
  if (!spec.details.empty()) out << "\n" << spec.details << "\n";
  return out.str();
}

}  // namespace fb::cli
