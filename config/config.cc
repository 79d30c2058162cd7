#include "config/config.h"

#include <boost/any.hpp>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <ostream>
#include <set>
#include <utility>

namespace reconduit::config {
namespace {

// The value as given ("" for a flag without one).
std::string TextOf(const po::option& option) {
  return option.value.empty() ? std::string() : option.value.front();
}

// The placeholders of a message ("%canonical_option%", "%invalid_line%") are filled in by
// what(), and Boost 1.74 replaces a placeholder until none is left: a value that contains its
// own placeholder (a config line "x %invalid_line%", found by fuzzing) loops forever. So the
// '%' of every substituted value is swapped for a byte messages never hold before what() runs,
// and swapped back in the text it returns.
struct SubstitutionsOf : po::error_with_option_name {
  static std::map<std::string, std::string>& Of(po::error_with_option_name& e) {
    return e.*(&SubstitutionsOf::m_substitutions);
  }
};

std::string MessageOf(const po::error& error) {
  const auto* named = dynamic_cast<const po::error_with_option_name*>(&error);
  if (named == nullptr) return error.what();
  po::error_with_option_name copy = *named;
  for (auto& [placeholder, value] : SubstitutionsOf::Of(copy)) {
    std::replace(value.begin(), value.end(), '%', '\x01');
  }
  std::string message = copy.what();
  std::replace(message.begin(), message.end(), '\x01', '%');
  return message;
}

// --help and --config, which every program has, followed by the program's options.
po::options_description AllOptions(const ProgramSettings& program) {
  std::string others;
  for (const std::string& section : kConfigSections) {
    if (section != program.section) others += (others.empty() ? "[" : ", [") + section + "]";
  }
  const std::string config_help =
      "Read settings from this file (env RECONDUIT_CONFIG): INI-style 'name = value' lines with "
      "the option names without '--'; '#' starts a comment. Names at the top are read by every "
      "program reading the file, names under [" +
      program.section + "] only by this one; " + others +
      " is skipped. An unknown name, a name set twice or a bad value is an error (exit "
      "status 2).";
  po::options_description all("Options", kHelpWidth, kHelpWidth / 2);
  // clang-format off
  all.add_options()
      ("help,h", "Print this help and exit.")
      ("config", po::value<std::string>()->value_name("FILE"), config_help.c_str());
  // clang-format on
  all.add(program.options);
  return all;
}

// Empty when `option` converts to its option's type, otherwise the message naming `where`.
std::string CheckType(const po::options_description& options,
                      const po::option& option,
                      const std::string& where) {
  const po::option_description* description = options.find_nothrow(option.string_key, false);
  if (description == nullptr) return "";
  try {
    boost::any value;
    // Not UTF-8 (the last argument): po::store takes the bytes as they are, and so does this
    // check. With UTF-8 a byte sequence that is not valid UTF-8 (a Latin-1 folder name) threw
    // std::logic_error "character conversion failed" out of ParseSettings (found by fuzzing).
    description->semantic()->parse(value, option.value, /*utf8=*/false);
  } catch (const po::error&) {
    return "invalid value '" + TextOf(option) + "' for " + where;
  }
  return "";
}

// Type-checks every option of `parsed`, then stores it under the values of earlier (stronger)
// places and records where new values came from.
std::string Store(const po::options_description& all,
                  const po::parsed_options& parsed,
                  const std::function<std::string(const po::option&)>& where_of,
                  Settings* settings) {
  for (const po::option& option : parsed.options) {
    if (std::string error = CheckType(all, option, where_of(option)); !error.empty()) {
      return error;
    }
  }
  for (const po::option& option : parsed.options) {
    const auto known = settings->values.find(option.string_key);
    if (known == settings->values.end() || known->second.defaulted()) {
      settings->origins.emplace(option.string_key,
                                Settings::Origin{where_of(option), TextOf(option)});
    }
  }
  try {
    po::store(parsed, settings->values);
  } catch (const po::error& e) {
    return MessageOf(e);
  }
  return "";
}

// The program's environment variables (and RECONDUIT_CONFIG) as options.
po::parsed_options ReadEnvironment(const ProgramSettings& program,
                                   const po::options_description& all,
                                   const GetEnv& getenv) {
  po::parsed_options parsed(&all);
  std::map<std::string, std::string> variables = program.environment;
  variables.emplace("config", "RECONDUIT_CONFIG");
  for (const auto& [option, variable] : variables) {
    const std::optional<std::string> value = getenv(variable);
    if (!value || value->empty()) continue;
    po::option parsed_option(option, {*value});
    parsed_option.original_tokens = {variable};
    parsed.options.push_back(std::move(parsed_option));
  }
  return parsed;
}

// The name of `key` ("port", "server.port") for this program: empty when the key belongs to
// another program's section. Sets *error for an unknown section.
std::string OwnName(const ProgramSettings& program, const std::string& key, std::string* error) {
  const std::size_t dot = key.find('.');
  if (dot == std::string::npos) return key;
  const std::string section = key.substr(0, dot);
  if (section == program.section) return key.substr(dot + 1);
  if (std::find(kConfigSections.begin(), kConfigSections.end(), section) == kConfigSections.end()) {
    *error = "unknown section [" + section + "]";
  }
  return "";
}

// The file's names for this program, renamed to their option names ("server.port" -> "port").
// The original names stay in original_tokens for messages.
std::string ReadConfigFile(const ProgramSettings& program,
                           const std::string& path,
                           po::parsed_options* parsed) {
  std::ifstream file(path);
  if (!file) return "cannot read the config file '" + path + "': " + std::strerror(errno);
  const std::string in = "config file '" + path + "': ";
  const po::options_description none;
  std::vector<po::option> raw;
  try {
    raw = po::parse_config_file(file, none, /*allow_unregistered=*/true).options;
  } catch (const po::error& e) {
    return in + MessageOf(e);
  }
  std::set<std::string> seen;
  for (po::option& option : raw) {
    const std::string key = option.string_key;
    std::string error;
    const std::string name = OwnName(program, key, &error);
    if (!error.empty()) return in + error;
    if (name.empty()) continue;
    if (program.options.find_nothrow(name, false) == nullptr) {
      return in + "unrecognised option '" + key + "'";
    }
    if (!seen.insert(name).second) return in + "'" + name + "' cannot be specified more than once";
    option.string_key = name;
    option.unregistered = false;
    option.original_tokens = {key};
    parsed->options.push_back(std::move(option));
  }
  return "";
}

}  // namespace

std::string EnvironmentName(const std::string& option) {
  std::string name = "RECONDUIT_";
  for (const char c : option) {
    name += c == '-' ? '_' : static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  }
  return name;
}

std::map<std::string, std::string> DefaultEnvironment(const po::options_description& options) {
  std::map<std::string, std::string> environment;
  for (const auto& option : options.options()) {
    environment.emplace(option->long_name(), EnvironmentName(option->long_name()));
  }
  return environment;
}

std::string Settings::From(const std::string& option) const {
  const auto it = origins.find(option);
  return it == origins.end() ? "" : " (from " + it->second.where + ")";
}

std::string Settings::Invalid(const std::string& option, const std::string& why) const {
  const auto it = origins.find(option);
  if (it == origins.end()) return "invalid value for '" + option + "': " + why;
  return "invalid value '" + it->second.text + "' for " + it->second.where + ": " + why;
}

std::optional<std::string> ProcessEnvironment(const std::string& name) {
  const char* value = std::getenv(name.c_str());
  if (value == nullptr) return std::nullopt;
  return std::string(value);
}

std::optional<int> ParseSettings(const ProgramSettings& program,
                                 const std::vector<std::string>& args,
                                 Settings* settings,
                                 std::ostream& out,
                                 std::ostream& err,
                                 const GetEnv& getenv) {
  const po::options_description all = AllOptions(program);
  const std::string prefix = program.program + ": ";
  // The command line first: --help needs nothing else to be valid.
  po::parsed_options command_line(&all);
  try {
    command_line = po::command_line_parser(args).options(all).run();
  } catch (const po::error& e) {
    err << prefix << MessageOf(e) << " (see --help)\n";
    return 2;
  }
  for (const po::option& option : command_line.options) {
    if (option.string_key == "help") {
      out << program.usage << "\n" << all << "\n" << program.epilogue;
      return 0;
    }
  }
  auto flag = [](const po::option& option) { return "--" + option.string_key; };
  if (std::string error = Store(all, command_line, flag, settings); !error.empty()) {
    err << prefix << error << " (see --help)\n";
    return 2;
  }
  // Stored second and third: a value from a stronger place is kept.
  auto variable = [](const po::option& option) { return option.original_tokens.front(); };
  const po::parsed_options environment = ReadEnvironment(program, all, getenv);
  if (std::string error = Store(all, environment, variable, settings); !error.empty()) {
    err << prefix << error << "\n";
    return 2;
  }
  if (settings->values.count("config") != 0) {
    const std::string path = settings->values["config"].as<std::string>();
    po::parsed_options file(&all);
    auto in_file = [&path](const po::option& option) {
      return "'" + option.original_tokens.front() + "' in config file '" + path + "'";
    };
    std::string error = ReadConfigFile(program, path, &file);
    if (error.empty()) error = Store(all, file, in_file, settings);
    if (!error.empty()) {
      err << prefix << error << "\n";
      return 2;
    }
  }
  try {
    po::notify(settings->values);
  } catch (const po::error& e) {
    err << prefix << MessageOf(e) << " (see --help)\n";
    return 2;
  }
  return std::nullopt;
}

}  // namespace reconduit::config
