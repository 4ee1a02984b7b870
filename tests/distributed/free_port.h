// A TCP port on 127.0.0.1 that is free right now (the kernel's choice for port 0), for
// rendezvous in tests. Another process could take it before the test binds it; the kernel
// hands out ephemeral ports in rotation, which makes that unlikely.
#pragma once

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <stdexcept>
#include <string>

namespace pumeta::test {

inline int free_port() {
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    if (fd < 0) throw std::runtime_error("socket() failed");
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    address.sin_port = 0;
    socklen_t length = sizeof address;
    if (bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0 ||
        getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length) != 0) {
        close(fd);
        throw std::runtime_error("could not bind a free port");
    }
    close(fd);
    return ntohs(address.sin_port);
}

inline std::string free_master() { return "127.0.0.1:" + std::to_string(free_port()); }

}  // namespace pumeta::test
