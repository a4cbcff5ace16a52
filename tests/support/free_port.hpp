#pragma once
// A free TCP port on 127.0.0.1 for a server a test starts (mosquitto, PostgreSQL): bound to port 0, read back and
// released, so that test programs running in parallel (ctest -j) never collide. 0 when none could be had.

#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

namespace feedid::testing {

inline int free_port() {
    const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    if (fd < 0) return 0;
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    address.sin_port = 0;
    socklen_t length = sizeof address;
    int port = 0;
    if (::bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0 &&
        ::getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length) == 0)
        port = ntohs(address.sin_port);
    ::close(fd);
    return port;
}

}  // namespace feedid::testing
