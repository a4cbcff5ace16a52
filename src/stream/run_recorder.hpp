#pragma once
// The history side of `feedid watch`: completed identifications go into an on-disk spool (run_spool.hpp) and a
// thread of their own writes them from there to the history, in order, each in its transaction; it publishes the
// run and the drift alarms it raises. A database that is away (a restart, a network cut) delays nothing else: the
// store retries a lost connection for db_retry_s with backoff, and after that the recorder tries again every 1, 2,
// 4, ... 30 s for as long as the service runs; what completes meanwhile waits in the spool, also across a restart of
// the service. A run the history refuses for good (another axis kind under the same name) is set aside in the
// spool's rejected/ folder, said, and does not block the others.

#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>

#include "feedid/history/store.hpp"
#include "feedid/stream/run_spool.hpp"
#include "feedid/stream/service.hpp"

namespace feedid::watch {

class RunRecorder {
public:
    /// Sends a message (topic, payload, QoS); called from the recorder's thread.
    using Publish = std::function<void(const std::string&, const std::string&, int)>;

    /// Opens the history (for writing) and its spool. InputError naming them when either cannot be opened.
    RunRecorder(const ServiceOptions& options, Publish publish);
    ~RunRecorder();
    RunRecorder(const RunRecorder&) = delete;
    RunRecorder& operator=(const RunRecorder&) = delete;

    /// Starts the writing thread (the spool may hold runs of an earlier watch: they go first).
    void start();
    /// A completed run into the spool, on disk when it returns. false (and said on stderr) when the spool is full
    /// or cannot be written: the run is lost.
    bool put(const nlohmann::json& entry);
    /// Stops: waits at most `seconds` for the spool to be written, then ends the retries and the thread. The runs
    /// left in the spool (written by the next watch on this history).
    std::size_t finish(double seconds);

    [[nodiscard]] std::size_t recorded() const { return recorded_; }
    [[nodiscard]] std::size_t lost() const { return lost_; }
    [[nodiscard]] std::size_t rejected() const { return rejected_; }
    [[nodiscard]] const RunSpool& spool() const { return spool_; }

private:
    void loop();
    /// Writes the spool's first run: true when it left the spool (written, or set aside as refused for good).
    bool write_first();
    void publish_alarms(const nlohmann::json& entry, std::int64_t run_id);
    /// Waits `seconds` or until stop; false when stopped.
    bool pause(double seconds);

    const ServiceOptions& options_;
    Publish publish_;
    std::atomic<bool> cancel_{false};  ///< ends the store's retries at once
    std::unique_ptr<history::HistoryStore> store_;
    RunSpool spool_;
    std::thread thread_;
    std::mutex mutex_;
    std::condition_variable wake_;
    bool stopping_{false};  ///< no more runs are coming: write what is there, then end
    std::atomic<std::size_t> recorded_{0}, lost_{0}, rejected_{0};
};

/// The spool folder of a history: ServiceOptions::spool_dir, or '<file>.spool' beside a SQLite file, or
/// 'feedid-spool-<first 12 hex digits of the location's SHA-256>' in the working folder for a database server.
std::string spool_folder(const ServiceOptions& options);

}  // namespace feedid::watch
