// The history side of feedid watch (run_recorder.hpp): spool, writing thread, alarms.
#include "run_recorder.hpp"

#include <chrono>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "feedid/core/terminal_text.hpp"
#include "feedid/core/version.hpp"
#include "feedid/history/sha256.hpp"
#include "feedid/history/trend.hpp"

namespace feedid::watch {
namespace {

history::OpenOptions open_options(const ServiceOptions& options, const std::atomic<bool>& cancel) {
    history::OpenOptions open;
    open.retry_s = options.db_retry_s;
    open.cancel = &cancel;
    return open;
}

/// The run record of a spool entry (as record() made it when the run completed).
history::RunRecord record_of(const nlohmann::json& entry) {
    const std::string source = entry.at("source").get<std::string>();
    history::RunRecord record = history::run_from_result(entry.at("result"), source);
    record.machine = entry.at("machine").get<std::string>();
    record.axis = entry.at("axis").get<std::string>();
    record.recorded_at = entry.at("recorded_at").get<std::string>();
    record.trace_path = source;
    record.trace_sha256 = entry.at("trace_sha256").get<std::string>();
    record.options = entry.at("options");
    if (record.feedid_version.empty()) record.feedid_version = feedid::version;
    return record;
}

}  // namespace

std::string spool_folder(const ServiceOptions& options) {
    if (!options.spool_dir.empty()) return options.spool_dir;
    if (!history::is_postgresql_location(options.database)) return options.database + ".spool";
    return "feedid-spool-" + history::sha256_hex(options.database).substr(0, 12);
}

RunRecorder::RunRecorder(const ServiceOptions& options, Publish publish)
    : options_(options),
      publish_(std::move(publish)),
      store_(history::open_store(options.database, open_options(options, cancel_))),
      spool_(spool_folder(options), options.spool_bytes) {}

RunRecorder::~RunRecorder() {
    finish(0.0);
}

void RunRecorder::start() {
    if (spool_.size() > 0)
        fmt::print(stderr,
                   "feedid watch: {} completed run(s) of an earlier watch wait in the spool {}: written first\n",
                   spool_.size(), spool_.folder().string());
    thread_ = std::thread([this] { loop(); });
}

bool RunRecorder::put(const nlohmann::json& entry) {
    const std::string what =
        fmt::format("{}/{} run {}", terminal_text(entry["machine"].get<std::string>()),
                    terminal_text(entry["axis"].get<std::string>()), entry["sequence"].get<std::size_t>());
    try {
        if (!spool_.put(entry)) {
            ++lost_;
            fmt::print(stderr, "feedid watch: {} lost: the spool {} is full ({} runs, {:.1f} MB; spool_mb)\n", what,
                       spool_.folder().string(), spool_.size(), static_cast<double>(spool_.bytes()) / (1 << 20));
            return false;
        }
    } catch (const std::exception& e) {
        ++lost_;
        fmt::print(stderr, "feedid watch: {} lost: {}\n", what, terminal_text(e.what()));
        return false;
    }
    wake_.notify_one();
    return true;
}

bool RunRecorder::pause(double seconds) {
    std::unique_lock lock(mutex_);
    wake_.wait_for(lock, std::chrono::duration<double>(seconds), [&] { return cancel_.load(); });
    return !cancel_;
}

void RunRecorder::loop() {
    double backoff = 1.0;
    bool away = false;
    while (!cancel_) {
        if (spool_.size() == 0) {
            std::unique_lock lock(mutex_);
            if (stopping_) return;
            wake_.wait_for(lock, std::chrono::milliseconds(200));
            continue;
        }
        try {
            if (write_first() && away) {
                fmt::print(stderr, "feedid watch: the history is back; {} run(s) still in the spool\n", spool_.size());
                away = false;
            }
            backoff = 1.0;
        } catch (const history::Unavailable& e) {  // the store retried for db_retry_s: keep them, try again later
            if (!away)
                fmt::print(stderr, "feedid watch: {}; the completed runs wait in the spool {} (now {})\n",
                           terminal_text(e.what()), spool_.folder().string(), spool_.size());
            away = true;
            if (!pause(backoff)) return;
            backoff = std::min(30.0, 2.0 * backoff);
        } catch (const std::exception& e) {  // out of memory and the like: try again later
            fmt::print(stderr, "feedid watch: writing a run to the history: {}\n", terminal_text(e.what()));
            if (!pause(backoff)) return;
            backoff = std::min(30.0, 2.0 * backoff);
        }
    }
}

bool RunRecorder::write_first() {
    const auto first = spool_.front();
    if (!first) return false;
    const nlohmann::json& entry = first->entry;
    history::AddOutcome outcome;
    try {
        outcome = store_->add_run(record_of(entry));
    } catch (const history::Unavailable&) {
        throw;
    } catch (const std::exception& e) {  // refused for good (InputError), or an entry that is not one
        ++rejected_;
        const std::string reason = terminal_text(e.what());
        spool_.reject(first->number, reason);
        fmt::print(stderr,
                   "feedid watch: a completed run was refused by the history and set aside in {}/rejected: {}\n",
                   spool_.folder().string(), reason);
        return true;
    }
    spool_.remove(first->number);
    ++recorded_;
    const std::string prefix = entry.value("prefix", std::string());
    publish_(prefix + "/feedid/run",
             nlohmann::json{{"run", outcome.id}, {"inserted", outcome.inserted}, {"result", entry["result"]}}.dump(
                 -1, ' ', false, nlohmann::json::error_handler_t::replace),
             1);
    if (outcome.inserted) {
        try {
            publish_alarms(entry, outcome.id);
        } catch (const std::exception& e) {  // the run is stored; its check can be made with history --check
            fmt::print(stderr, "feedid watch: the drift check of run {} failed: {}\n", outcome.id,
                       terminal_text(e.what()));
        }
    }
    return true;
}

void RunRecorder::publish_alarms(const nlohmann::json& entry, std::int64_t run_id) {
    history::RunFilter filter;
    filter.machine = entry["machine"].get<std::string>();
    filter.axis = entry["axis"].get<std::string>();
    history::TrendOptions trend;
    trend.keep_points = false;
    const std::string prefix = entry.value("prefix", std::string());
    for (const auto& series : history::analyse_trends(store_->series(filter), store_->pins(), trend)) {
        for (const history::Alarm& alarm : series.alarms) {
            if (alarm.run_id != run_id) continue;
            const nlohmann::json message = history::alarm_document(alarm);
            publish_(prefix + "/feedid/alarm", message.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace),
                     1);
            if (options_.print) fmt::print("ALARM {}\n", terminal_text(alarm.message()));
        }
    }
    if (options_.print) std::fflush(stdout);
}

std::size_t RunRecorder::finish(double seconds) {
    if (thread_.joinable()) {
        {
            std::lock_guard lock(mutex_);
            stopping_ = true;
        }
        wake_.notify_all();
        const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
        while (spool_.size() > 0 && std::chrono::steady_clock::now() < until)
            std::this_thread::sleep_for(std::chrono::milliseconds(20));
        cancel_ = true;  // the store's retries and the pauses end now
        wake_.notify_all();
        thread_.join();
    }
    return spool_.size();
}

}  // namespace feedid::watch
