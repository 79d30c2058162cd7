// The settings of a long-running program (reconduit-server, reconduit-worker) from four places,
// with one precedence: command line > environment > configuration file > defaults.
//
// Each program describes its settings once, as a boost::program_options table (names, types,
// defaults, help), says which environment variable sets which option, and names its section of
// the configuration file. ParseSettings reads all four places and reports every problem the same
// way: one line on stderr naming the program and the place ("--lease", "RECONDUIT_PORT",
// "'threads' in config file 'x.conf'"), and exit status 2.
//
// The configuration file (--config FILE or RECONDUIT_CONFIG) is INI-style and may serve both
// programs at once:
//
//   data = /srv/reconduit        # top level: every program reading the file knows the name
//   [server]
//   port = 8080                  # only reconduit-server reads [server]
//   [worker]
//   lease = 60                   # only reconduit-worker reads [worker]
//
// A program reads the top-level names and its own section and skips the other known sections
// (kConfigSections). Top-level names are shared: each program that reads the file must know
// them, so only names both programs have (data) belong there in a shared file; a file written
// for one program (no sections, as before sections existed) keeps working for that program.
// Errors: an unknown name at the top or in the program's own section, an unknown section, a name
// set twice (also once at the top and once in the section) and a value of the wrong type.
#ifndef RECONDUIT_CONFIG_CONFIG_H_
#define RECONDUIT_CONFIG_CONFIG_H_

#include <boost/program_options.hpp>

#include <functional>
#include <iosfwd>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace reconduit::config {

namespace po = boost::program_options;

// The sections a configuration file may have; a program skips those that are not its own.
inline const std::vector<std::string> kConfigSections = {"server", "worker"};

// The width of --help's option table.
inline constexpr unsigned kHelpWidth = 100;

// What one program accepts.
struct ProgramSettings {
  // "reconduit-server": the first word of every message.
  std::string program;
  // "server": the program's section of the configuration file.
  std::string section;
  // Printed by --help before the option table, and after it.
  std::string usage;
  std::string epilogue;
  // Every setting (without --help and --config, which ParseSettings adds): flags of the same
  // name, environment variables per `environment`, names in the configuration file.
  // kHelpWidth columns wide in --help.
  po::options_description options{kHelpWidth, kHelpWidth / 2};
  // Option name -> environment variable ("lease" -> "RECONDUIT_LEASE_SECONDS"). Options not
  // listed have none. RECONDUIT_CONFIG always names the configuration file.
  std::map<std::string, std::string> environment;
};

// "max-upload-bytes" -> "RECONDUIT_MAX_UPLOAD_BYTES".
std::string EnvironmentName(const std::string& option);

// option -> EnvironmentName(option) for every option of `options`.
std::map<std::string, std::string> DefaultEnvironment(const po::options_description& options);

// The values after ParseSettings, and where each came from.
struct Settings {
  po::variables_map values;
  // Option -> where its value was given ("--port", "RECONDUIT_PORT", "'port' in config file
  // 'x.conf'") and the text given there. Options left at their defaults are absent.
  struct Origin {
    std::string where;
    std::string text;
  };
  std::map<std::string, Origin> origins;

  // " (from WHERE)" when the option was given somewhere, "" at its default.
  std::string From(const std::string& option) const;
  // "invalid value 'TEXT' for WHERE: why", or "invalid value for 'option': why" at its default:
  // for values of the right type that the program rejects (out of range, unknown stage).
  std::string Invalid(const std::string& option, const std::string& why) const;
};

// Looks up an environment variable; std::getenv by default, a map in tests.
using GetEnv = std::function<std::optional<std::string>(const std::string& name)>;
std::optional<std::string> ProcessEnvironment(const std::string& name);

// Reads `args` (without the program name), the environment and the configuration file into
// *settings and runs the options' notifiers. Returns an exit status when the program should stop
// now: 0 after --help (printed to `out`), 2 after a problem (one line printed to `err`).
// Environment variables set to "" count as unset.
std::optional<int> ParseSettings(const ProgramSettings& program,
                                 const std::vector<std::string>& args,
                                 Settings* settings,
                                 std::ostream& out,
                                 std::ostream& err,
                                 const GetEnv& getenv = ProcessEnvironment);

}  // namespace reconduit::config

#endif  // RECONDUIT_CONFIG_CONFIG_H_
