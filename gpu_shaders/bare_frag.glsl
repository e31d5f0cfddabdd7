/* Depth only: no colour output, the rasterizer's depth is stored. */
void main()
{
}
