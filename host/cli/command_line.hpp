// A small declarative command-line parser: each command declares its options once, and
// the same declaration produces the parser and the --help text, so help cannot drift.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "algo/core/result.hpp"

namespace fb::cli {

struct OptionSpec {
  std::string name;        // without leading dashes, e.g. "camera"
  std::string value_name;  // empty for a flag, else e.g. "URI"
  std::string help;
  std::string default_value;  // shown in help; used when the option is absent
};

struct CommandSpec {
  std::string path;     // e.g. "camera record"
  std::string summary;  // one line
  std::string details;  // optional paragraph after the options
  std::vector<OptionSpec> options;
};

class ParsedOptions {
 public:
  bool flag(const std::string& name) const { return values_.count(name) > 0; }
  std::string get(const std::string& name) const;
  Result<long long> get_int(const std::string& name) const;
  Result<double> get_double(const std::string& name) const;
  // Every value of an option given more than once, in order (get() returns the last).
  std::vector<std::string> all(const std::string& name) const {
    auto it = all_.find(name);
    return it == all_.end() ? std::vector<std::string>{} : it->second;
  }
  bool help_requested = false;

 private:
  friend Result<ParsedOptions> parse_options(const CommandSpec&, const std::vector<std::string>&,
                                             std::string_view);
  std::map<std::string, std::string> values_;
  std::map<std::string, std::string> defaults_;
  std::map<std::string, std::vector<std::string>> all_;
};

// `program` names the binary in messages and help: "facebooth" or "facebooth-lab".
Result<ParsedOptions> parse_options(const CommandSpec& spec, const std::vector<std::string>& args,
                                    std::string_view program = "facebooth");
std::string format_help(const CommandSpec& spec, std::string_view program = "facebooth");

}  // namespace fb::cli
