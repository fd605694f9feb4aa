/* Minimal C client of the agrihil software bus (socketcand protocol), for tests.
 * usage: softbus_client PORT  -- joins can0, sends frame 0x123 [de ad], waits for one frame
 * and prints it as "ID DATAHEX". Plain POSIX sockets, no allocation. */
#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

static int expect(int fd, const char *want) {
    char buf[64];
    ssize_t n = recv(fd, buf, sizeof buf - 1, 0);
    if (n <= 0) return -1;
    buf[n] = '\0';
    return strcmp(buf, want) == 0 ? 0 : -1;
}

int main(int argc, char **argv) {
    if (argc != 2) return 2;
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    int one = 1;
    setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    struct sockaddr_in addr = {.sin_family = AF_INET, .sin_port = htons((uint16_t)atoi(argv[1]))};
    inet_pton(AF_INET, "127.0.0.1", &addr.sin_addr);
    if (connect(fd, (struct sockaddr *)&addr, sizeof addr) != 0) return 3;
    if (expect(fd, "< hi >")) return 4;
    send(fd, "< open can0 >", 13, 0);
    if (expect(fd, "< ok >")) return 5;
    send(fd, "< rawmode >", 11, 0);
    if (expect(fd, "< ok >")) return 6;
    const char *frame = "< send 123 2 de ad >";
    send(fd, frame, strlen(frame), 0);
    char buf[256];
    size_t used = 0;
    for (;;) {  /* read until one complete "< frame ... >" */
        ssize_t n = recv(fd, buf + used, sizeof buf - 1 - used, 0);
        if (n <= 0) return 7;
        used += (size_t)n;
        buf[used] = '\0';
        char *start = strstr(buf, "< frame ");
        if (start && strchr(start, '>')) {
            char id[16], stamp[32], data[32];
            if (sscanf(start, "< frame %15s %31s %31s >", id, stamp, data) != 3) return 8;
            printf("%s %s\n", id, data);
            break;
        }
    }
    close(fd);
    return 0;
}
