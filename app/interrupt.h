// Ctrl-C (SIGINT) and SIGTERM for the command-line front end (README: exit
// code 130, one line on stderr, no output written).
//
// A command runs in two kinds of phase. Until it calls startPolling() -
// argument checks, plugin and scene loading, subdivision, the BVH build:
// work that cannot stop half-way and writes no file - a signal ends the
// process at once: the handler writes the current message with write(2) and
// calls _exit(130) (both async-signal-safe), so nothing is left half-written.
// From startPolling() on, the handler only raises the flag; the render loop
// checks it every chunk of samples, the command says what it kept and
// returns 130. An output being written then (temporary file + rename)
// completes first.
#pragma once

#include <atomic>
#include <string>

namespace obscura::interrupt {

// Installs the handler for SIGINT and SIGTERM (once, at the start of main).
void install();
// The line an immediate exit writes (without the newline); copied. Default:
// "obscura: interrupted".
void setMessage(const std::string& line);
// From now on a signal only raises flag(): the caller polls it.
void startPolling();
// Raised by the first signal.
const std::atomic<bool>* flag();

}  // namespace obscura::interrupt
