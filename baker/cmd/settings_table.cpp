// SettingsTable: options, help defaults, the --config reader and the settings' JSON, from one row per setting.
#include "baker/cmd/settings_table.h"

#include <cstdio>
#include <cstdlib>
#include <stdexcept>

namespace nrad {

namespace {

template <typename... F>
struct Overloaded : F... {
    using F::operator()...;
};
template <typename... F>
Overloaded(F...) -> Overloaded<F...>;

// The default as the help shows it: a number, a non-empty string; nothing for a flag.
std::string defaultText(const SettingsTable::Value& value) {
    return std::visit(Overloaded{[](bool*) { return std::string(); }, [](std::string* p) { return *p; },
                                 [](float* p) {
                                     char b[32];
                                     std::snprintf(b, sizeof b, "%g", double(*p));
                                     return std::string(b);
                                 },
                                 [](auto* p) { return std::to_string(*p); }},
                      value);
}

// A --config value as the text its flag would take: a string as it is, a number as JSON writes it (which reads
// back to the same value), an array of numbers comma-separated.
std::string flagText(const nlohmann::json& v) {
    if (v.is_string()) return v.get<std::string>();
    if (v.is_number()) return v.dump();
    if (v.is_array() && !v.empty()) {
        std::string text;
        for (const nlohmann::json& x : v) {
            if (!x.is_number()) throw std::runtime_error("expected numbers in the array");
            text += (text.empty() ? "" : ",") + x.dump();
        }
        return text;
    }
    throw std::runtime_error("expected a number or a string, not " + v.dump());
}

}  // namespace

nlohmann::json SettingsTable::Row::json() const {
    return std::visit(Overloaded{[this](bool* p) { return nlohmann::json(negated() ? !*p : *p); },
                                 [](float* p) {
                                     // The shortest text that reads back as the same float (0.99, not 0.9900000095).
                                     char b[32];
                                     for (int digits = 6; digits <= 9; ++digits) {
                                         std::snprintf(b, sizeof b, "%.*g", digits, double(*p));
                                         if (std::strtof(b, nullptr) == *p) break;
                                     }
                                     return nlohmann::json(std::strtod(b, nullptr));
                                 },
                                 [](auto* p) { return nlohmann::json(*p); }},
                      value);
}

SettingsTable::Row& SettingsTable::add(std::string flag, Value value, std::string help) {
    const bool negated = std::holds_alternative<bool*>(value) && flag.compare(0, 5, "--no-") == 0;
    std::string key = flag.substr(negated ? 5 : 2);
    for (char& c : key) c = c == '-' ? '_' : c;
    rows_.push_back(Row{std::move(key), std::move(flag), std::move(help), value, {}, {}});
    return rows_.back();
}

void SettingsTable::addOptions(CLI::App* cmd) const {
    for (const Row& row : rows_) {
        const std::string text = row.defaultText.empty() ? defaultText(row.value) : row.defaultText;
        const std::string help = row.help + (text.empty() ? "" : " (default " + text + ")");
        CLI::Option* option = std::visit(Overloaded{[&](bool* p) { return cmd->add_flag(row.flag, *p, help); },
                                                    [&](auto* p) { return cmd->add_option(row.flag, *p, help); }},
                                         row.value);
        if (row.check) row.check(option);
    }
}

std::set<std::string> SettingsTable::readConfig(const nlohmann::json& cfg, const CLI::App* cmd) const {
    std::set<std::string> given;
    for (const auto& [key, v] : cfg.items()) {
        const Row* row = nullptr;
        for (const Row& r : rows_) row = r.key == key ? &r : row;
        if (!row) throw std::runtime_error("unknown key '" + key + "'");
        given.insert(key);
        if (cmd->count(row->flag) > 0) continue;  // the flag wins
        try {
            if (bool* const* flag = std::get_if<bool*>(&row->value)) {
                if (!v.is_boolean()) throw std::runtime_error("expected true or false, not " + v.dump());
                **flag = row->negated() ? !v.get<bool>() : v.get<bool>();
                continue;
            }
            // The value goes through an option of its own made like the flag's: the same conversion and checks.
            CLI::App one;
            CLI::Option* option = std::visit([&](auto* p) { return one.add_option(row->flag, *p); }, row->value);
            if (row->check) row->check(option);
            one.parse(std::vector<std::string>{row->flag + "=" + flagText(v)});
        } catch (const CLI::ParseError& e) {
            throw std::runtime_error("\"" + key + "\": " + e.what());
        } catch (const std::runtime_error& e) {
            throw std::runtime_error("\"" + key + "\": " + e.what());
        }
    }
    return given;
}

nlohmann::json SettingsTable::json() const {
    nlohmann::json j = nlohmann::json::object();
    for (const Row& row : rows_) {
        const std::string* text = std::get_if<std::string*>(&row.value) ? *std::get_if<std::string*>(&row.value) : nullptr;
        if (!text || !text->empty()) j[row.key] = row.json();  // an empty string is a setting not given
    }
    return j;
}

}  // namespace nrad
