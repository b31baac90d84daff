// A command's settings, one row each: its --config key, its flag, its help, its checks and the variable that
// holds its value. The variable's value when the row is added is the setting's one default; the command's
// CLI11 options, the defaults its help shows, the --config reader and its unknown-key refusal, and the JSON of
// the settings a run used (--dump-config, --stats) are all made from the rows (pbrt's GetOneInt("maxdepth", 5)
// with ReportUnused, as a table).
#pragma once

#include <cstdint>
#include <functional>
#include <set>
#include <string>
#include <variant>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

namespace nrad {

class SettingsTable {
public:
    // A flag's `bool` is true when the flag is given. A row's key is its flag's name with underscores for dashes,
    // without the "--no-" of a flag that turns something off ("--no-metadata": "metadata": false), so that every
    // key says what is on.
    using Value = std::variant<bool*, int*, uint32_t*, uint64_t*, float*, std::string*>;

    struct Row {
        std::string key, flag, help;
        Value value;
        // The default as the help shows it: empty, the value's own text (none for a flag or an empty string);
        // else this text, for a default that depends on other settings.
        std::string defaultText;
        // Validators and transforms: applied to the flag and to the --config value alike.
        std::function<void(CLI::Option*)> check;

        Row& describeDefault(std::string text) {
            defaultText = std::move(text);
            return *this;
        }
        Row& checkedBy(std::function<void(CLI::Option*)> f) {
            check = std::move(f);
            return *this;
        }
        // Whether the key is the flag's negation ("--no-metadata" and "metadata").
        bool negated() const { return flag.compare(0, 5, "--no-") == 0; }
        // The value as --config would give it (a negated flag's `bool` inverted).
        nlohmann::json json() const;
    };

    // `flag`: "--name" (a `bool*` value: also "--no-name").
    Row& add(std::string flag, Value value, std::string help);
    const std::vector<Row>& rows() const { return rows_; }

    // Adds every row's option to `cmd`, its help ending in "(default X)".
    void addOptions(CLI::App* cmd) const;
    // Reads a --config object: every key's value, converted and checked as its flag's would be, unless the flag
    // was given on `cmd`'s command line (the flag wins). Throws std::runtime_error naming the key for an
    // unknown key or a bad value. Returns the keys the file gave.
    std::set<std::string> readConfig(const nlohmann::json& cfg, const CLI::App* cmd) const;
    // Every setting's value, keyed as --config reads them: a config file that repeats this run's settings.
    nlohmann::json json() const;

private:
    std::vector<Row> rows_;
};

}  // namespace nrad
