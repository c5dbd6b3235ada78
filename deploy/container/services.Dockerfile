# PostgreSQL 15, Redis 7 and Mosquitto 2 from Debian 12's packages, on the same locally made base, for sites
# without an image registry (and for tests/deploy): stand-ins for the official images deploy/compose.yaml names
# (postgres:15-bookworm, redis:7-bookworm, eclipse-mosquitto:2), with the parts of their interface it uses.
#   podman build -f deploy/container/services.Dockerfile --target postgres -t localhost/postgres:15 deploy/container
ARG BASE=localhost/mission-dispatch-base:bookworm

FROM ${BASE} AS postgres
RUN apt-get update && apt-get install -y --no-install-recommends postgresql-15 && rm -rf /var/lib/apt/lists/*
COPY postgres-entrypoint /usr/local/bin/postgres-entrypoint
ENV PGDATA=/var/lib/postgresql/data PATH=/usr/lib/postgresql/15/bin:/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin
EXPOSE 5432
ENTRYPOINT ["/usr/local/bin/postgres-entrypoint"]
CMD ["postgres"]

FROM ${BASE} AS redis
RUN apt-get update && apt-get install -y --no-install-recommends redis-server && rm -rf /var/lib/apt/lists/*
USER redis
EXPOSE 6379
CMD ["redis-server", "--protected-mode", "no"]

FROM ${BASE} AS mosquitto
RUN apt-get update && apt-get install -y --no-install-recommends mosquitto && rm -rf /var/lib/apt/lists/*
EXPOSE 1883 8883
CMD ["mosquitto", "-c", "/etc/mosquitto/mosquitto.conf"]
