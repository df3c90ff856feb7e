"""File formats: RINEX observation/navigation, pseudolite observation tables and site
files, solution writers (.pos, CSV, NMEA). Knows nothing about filters."""
