#version 330 core
// Shadow pass: only depth matters; an empty body lets the driver skip colour work.
void main() {}
