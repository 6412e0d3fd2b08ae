#include "config_file.h"

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <set>

#include <nlohmann/json.hpp>

#include "hivox/core/error.h"
#include "hivox/core/version.h"
#include "hivox/io/atomic_file.h"

namespace hivox::cli {

namespace {

using nlohmann::json;

const std::set<std::string>& excluded() {
  static const std::set<std::string> names = {"--out",      "--overwrite",  "--quiet", "--config",
                                              "--save-map", "--map",        "--help",  "--view",
                                              "--view-fps", "--view-linger"};
  return names;
}

/// Whether the command line gives option `name` itself (`--name VALUE` or `--name=VALUE`).
bool given(const std::vector<std::string>& args, std::size_t from, const std::string& name) {
  for (std::size_t i = from; i < args.size(); ++i)
    if (args[i] == name || args[i].rfind(name + "=", 0) == 0) return true;
  return false;
}

std::string number_text(const json& v) {
  return v.is_number_integer() ? std::to_string(v.get<int64_t>()) : v.dump();
}

/// A value as the command line takes it; empty optional-less means "flag given".
std::string value_text(const json& v, const std::string& file, const std::string& name) {
  if (v.is_string()) return v.get<std::string>();
  if (v.is_number()) return number_text(v);
  if (v.is_array()) {
    std::string out;
    for (const json& e : v) {
      if (!e.is_number() && !e.is_string())
        fail(ErrorCode::InvalidData, "{}: option {}: a list may hold numbers and strings only",
             file, name);
      out += (out.empty() ? "" : ",") + (e.is_string() ? e.get<std::string>() : number_text(e));
    }
    return out;
  }
  fail(ErrorCode::InvalidData, "{}: option {}: {} is not a number, string, boolean or list", file,
       name, v.dump());
}

}  // namespace

std::vector<std::string> expand_config_args(const std::vector<std::string>& args,
                                            const CLI::App& app) {
  std::string file;
  std::size_t command = args.size();
  for (std::size_t i = 1; i < args.size(); ++i) {
    if (command == args.size() && !args[i].empty() && args[i][0] != '-') command = i;
    if (args[i] == "--config" && i + 1 < args.size()) file = args[i + 1];
    if (args[i].rfind("--config=", 0) == 0) file = args[i].substr(9);
  }
  if (file.empty() || command == args.size()) return args;
  // `hivox experiment --config FILE` names configurations to compare, not its own settings.
  if (args[command] == "experiment") return args;
  json config;
  try {
    config = json::parse(read_whole_file(file));
  } catch (const json::exception& e) {
    fail(ErrorCode::InvalidData, "{}: not a valid JSON config file ({})", file, e.what());
  }
  if (!config.is_object() || !config.contains("options") || !config["options"].is_object())
    fail(ErrorCode::InvalidData, "{}: a config file is a JSON object with \"options\"", file);
  if (config.contains("command") && config["command"] != args[command])
    fail(ErrorCode::InvalidArgument, "{}: written by `hivox {}`, used with `hivox {}`", file,
         config["command"].is_string() ? config["command"].get<std::string>() : "?", args[command]);
  const std::string& command_name = args[command];
  const std::vector<const CLI::App*> found =
      app.get_subcommands([&](const CLI::App* sub) { return sub->get_name() == command_name; });
  const CLI::App* cmd = found.empty() ? nullptr : found.front();
  std::vector<std::string> inserted;
  for (const auto& [name, value] : config["options"].items()) {
    if (name.rfind("--", 0) != 0)
      fail(ErrorCode::InvalidData, "{}: option '{}' does not start with --", file, name);
    if (cmd != nullptr && cmd->get_option_no_throw(name) == nullptr)
      fail(ErrorCode::InvalidData, "{}: `hivox {}` has no option {}", file, args[command], name);
    if (excluded().count(name) || given(args, command + 1, name)) continue;
    if (value.is_boolean()) {
      if (value.get<bool>()) inserted.push_back(name);
      continue;
    }
    if (value.is_null()) continue;  // an option without a value (unset)
    inserted.push_back(name);
    inserted.push_back(value_text(value, file, name));
  }
  std::vector<std::string> out(args.begin(), args.begin() + static_cast<long>(command) + 1);
  out.insert(out.end(), inserted.begin(), inserted.end());
  out.insert(out.end(), args.begin() + static_cast<long>(command) + 1, args.end());
  return out;
}

std::string effective_config_json(const CLI::App& cmd) {
  json options = json::object();
  for (const CLI::Option* o : cmd.get_options()) {
    const std::string name = o->get_lnames().empty() ? "" : "--" + o->get_lnames().front();
    if (name.empty() || excluded().count(name) || o->get_positional()) continue;
    if (o->get_expected_max() == 0) {  // a flag
      options[name] = o->count() > 0;
      continue;
    }
    std::vector<std::string> values = o->count() > 0 ? o->results() : std::vector<std::string>{};
    if (values.empty()) {
      const std::string d = o->get_default_str();
      if (d.empty()) {
        options[name] = nullptr;
        continue;
      }
      values = {d};
    }
    auto typed = [](const std::string& s) -> json {
      char* end = nullptr;
      errno = 0;
      const double v = std::strtod(s.c_str(), &end);
      if (!s.empty() && end == s.c_str() + s.size() && errno == 0) {
        if (s.find_first_of(".eE") == std::string::npos) return static_cast<int64_t>(v);
        return v;
      }
      return s;
    };
    // Lists: "[4,6,10]" (a default) or several results, or "4,6,10" for a delimited option.
    std::string joined;
    for (const std::string& v : values) joined += (joined.empty() ? "" : ",") + v;
    if (o->get_expected_max() > 1) {
      if (!joined.empty() && joined.front() == '[' && joined.back() == ']')
        joined = joined.substr(1, joined.size() - 2);
      json list = json::array();
      std::string item;
      for (std::size_t i = 0; i <= joined.size(); ++i) {
        if (i == joined.size() || joined[i] == ',') {
          if (!item.empty()) list.push_back(typed(item));
          item.clear();
        } else if (joined[i] != ' ') {
          item += joined[i];
        }
      }
      options[name] = list;
    } else {
      options[name] = typed(joined);
    }
  }
  json out;
  out["hivox_version"] = std::string(library_version());
  out["command"] = cmd.get_name();
  out["options"] = options;
  return out.dump(2) + "\n";
}

}  // namespace hivox::cli
