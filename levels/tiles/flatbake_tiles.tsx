<?xml version="1.0" encoding="UTF-8"?>
<tileset version="1.8" tiledversion="1.8.2" name="flatbake" tilewidth="8" tileheight="8" tilecount="4" columns="4">
 <image source="flatbake_tiles.png" width="32" height="8"/>
 <tile id="0">
  <properties>
   <property name="flatbake" value="wall"/>
   <property name="reflectance" type="float" value="0.6"/>
  </properties>
 </tile>
 <tile id="1">
  <properties>
   <property name="emission" value="4 3.4 2.4"/>
   <property name="flatbake" value="emitter"/>
  </properties>
 </tile>
 <tile id="2">
  <properties>
   <property name="albedo" type="float" value="0.25"/>
   <property name="flatbake" value="floor"/>
  </properties>
 </tile>
 <tile id="3">
  <properties>
   <property name="flatbake" value="wall"/>
   <property name="reflectance" value="0.6 0.2 0.15"/>
  </properties>
 </tile>
</tileset>
